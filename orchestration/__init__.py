"""Co-simulation of FMI 2.0 units on fmpy, and the paper's closed loop as two FMUs.

The general master, one module per job:

* :mod:`.connections` -- the system: units, connections, validation against the model
  descriptions;
* :mod:`.schedule` -- the exchange schedule and the Gauss-Seidel order, from the declared
  output dependencies;
* :mod:`.instances` -- the FMU instances of a run: life cycle, fmpy's typed FMI functions,
  failures, log messages;
* :mod:`.exchange` -- the exchange at a communication point;
* :mod:`.step` -- one macro step (Jacobi, Gauss-Seidel; zero-order hold, linear
  extrapolation);
* :mod:`.step_control` -- the coupling-error estimate and the step-size update;
* :mod:`.fixed`, :mod:`.adaptive` -- the fixed-step and the step-size-controlled drivers;
* :mod:`.recorder`, :mod:`.results` -- the recorded rows and the result of a run;
* :mod:`.master` -- the public :class:`~.master.Master` (also made from an SSP package,
  :meth:`~.master.Master.from_ssp`);
* :mod:`.ssp` -- SSP 1.0 packages: write, validate against the schemas, read;
* :mod:`.hosts` -- other hosts of an SSP package: Ecos (API and command line), fmpy's
  ``simulate_ssp``.

The drill-string closed loop on top of it: :mod:`.closed_loop` (the master of the loop's SSP
package, the start values of an experiment, the model it runs), :mod:`.monolithic` (its
monolithic twin),
:mod:`.figures` (Figs. 5 and 6), :mod:`.crosscheck` (convergence in the macro step) and
:mod:`.loop_ssp` (the loop as SSP packages, scaled and SI; ``docs/si_fmus.md``).
"""

from drillstring.orchestration.master import (
    Connection,
    CosimResult,
    FmuFailure,
    Master,
    StepControl,
    StepStats,
    Unit,
)

__all__ = ["Master", "StepControl", "Unit", "Connection", "CosimResult", "FmuFailure", "StepStats"]

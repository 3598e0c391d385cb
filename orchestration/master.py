"""A general FMI 2.0 co-simulation master on fmpy: the public :class:`Master`.

:class:`Master` couples FMI 2.0 co-simulation units (fmpy ``FMU2Slave``) described by a list of
:class:`~drillstring.orchestration.connections.Unit` and a connection list
``"unit.output -> unit.input"`` (validated by
:func:`~drillstring.orchestration.connections.build_system`). It is not tied to the
drill-string FMUs.

A run, in FMI 2.0 terms (standard section 4.2.4, state machine of a co-simulation slave):

1. instantiate, ``fmi2SetupExperiment``, start values (:mod:`.instances`);
2. ``fmi2EnterInitializationMode``, exchange, ``fmi2ExitInitializationMode``, exchange: outputs
   read and inputs written in dependency order (:mod:`.schedule`, :mod:`.exchange`), so every
   input holds the value of its source before the first step -- none starts at a default 0 the
   system never had (for an acyclic system this is what libcosim's N rounds of
   set/read/transfer give);
3. macro steps ``t_n -> t_n + H`` (:mod:`.step`: Jacobi or Gauss-Seidel, zero-order hold or
   linear extrapolation), each followed by the exchange at ``t_n + H`` (``exchange=
   "propagate"``: the schedule; ``"simple"``: libcosim's read-all-then-write-all, which delays
   a signal through a feedthrough unit by one macro step, an ``O(H)`` change of the result)
   and one recorded row (:mod:`.recorder`);
4. the step size: fixed (:mod:`.fixed`; ``grid="ns"`` is libcosim's integer-nanosecond time
   grid, so that ``exchange="simple", grid="ns"`` reproduces a libcosim run bit for bit;
   ``grid="sum"`` is the accumulated time of Ecos and of fmpy's SSP simulator) or
   controlled by the coupling-error estimate with rollback (:mod:`.adaptive`,
   :mod:`.step_control`).

:meth:`Master.from_ssp` builds the same master from an SSD of an SSP 1.0 package (:mod:`.ssp`):
its components, connections and parameter bindings (or named parameter sets), parameter values
converted into the FMUs' units, so that a plant or controller is swapped by naming another FMU,
not by writing Python wiring. Connections between FMU variables of different units of one
dimension convert the value (:mod:`.connections`).

FMU failures (a call returning fmi2Discard, fmi2Error or fmi2Fatal, or failing to instantiate)
stop the run cleanly: the returned :class:`CosimResult` holds the trajectories up to the last
good communication point and a :class:`FmuFailure` naming the unit, the FMI function, the time
and the unit's log messages (captured through the fmpy logger callback).

The stepping loop works on preallocated ctypes buffers that alias numpy arrays and calls the
FMUs' C functions (typed by fmpy) directly, with value references resolved once. A fixed-step
Jacobi run (the default; zero-order hold or linear extrapolation) runs that loop in C
(:mod:`.native_loop`: the same calls in the same order, the same bits, the progress bar advanced
every 1000 steps): a macro step of the Fig. 5 loop then takes about 1 us in all
(``bench/cosim.py``). Gauss-Seidel, step-size control, ``DRILLSTRING_MASTER_NATIVE=0`` or no C
compiler run it in Python (a few microseconds of the master's own per step).
"""

from __future__ import annotations

import logging
import math
import time as _time
import weakref
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Literal

import numpy as np
from fmpy import extract
from tqdm import tqdm

from drillstring.fileio import temporary_folder
from drillstring.model.units import UnitDef, UnitMismatch, unit_conversion
from drillstring.orchestration.adaptive import run_adaptive
from drillstring.orchestration.connections import (
    Connection,
    System,
    Unit,
    build_system,
    read_fmu_description,
    unit_definitions,
    variable_unit,
)
from drillstring.orchestration.fixed import n_steps, run_fixed
from drillstring.orchestration.instances import Instances, UnitFailure
from drillstring.orchestration.results import CosimResult, FmuFailure, StepStats
from drillstring.orchestration.run import Run, RunOptions
from drillstring.orchestration.ssp import SspError, SspPackage, SspParameter, read_ssp
from drillstring.orchestration.step_control import StepControl
from drillstring.validation import check_choice, check_real

__all__ = [
    "Master",
    "StepControl",
    "Unit",
    "Connection",
    "CosimResult",
    "FmuFailure",
    "StepStats",
]

log = logging.getLogger(__name__)

Scheme = Literal["jacobi", "gauss-seidel"]
Extrapolation = Literal["zoh", "linear"]
ExchangeMode = Literal["propagate", "simple"]


class Master:
    """Co-simulation master for FMI 2.0 co-simulation units (see the module docstring).

    FMUs are extracted once, into a temporary directory removed by :meth:`close` (or on
    garbage collection, at exit, and on SIGTERM: :func:`drillstring.fileio.temporary_folder`);
    each :meth:`run` instantiates fresh units and frees them.

    Parameters
    ----------
    units : sequence of Unit, or mapping
        The units, or name -> :class:`Unit`, FMU path or (FMU path, start values).
    connections : iterable
        ``"a.y -> b.u"`` strings, ``(source, target)`` pairs or :class:`Connection`.
    record : sequence of str
        Extra ``"unit.var"`` to record (Real, Integer, Boolean; connected variables are
        always recorded).
    gs_order : sequence of str, optional
        Unit names in Gauss-Seidel order (default from the declared dependencies).
    log_categories : sequence of str, optional
        FMU log categories to switch on (``fmi2SetDebugLogging``). None (default) switches on
        all of them so that a failing FMU's message is never filtered away (pythonfmu, for
        one, reports Python exceptions with an empty category); ``()`` switches logging off.

    Raises
    ------
    ValueError
        For an invalid system (:func:`~.connections.build_system`), a variable that cannot be
        recorded, or two units of an FMU that can be instantiated only once per process.
    """

    def __init__(
        self,
        units: Sequence[Unit] | Mapping[str, Unit | str | Path | tuple[str | Path, Mapping]],
        connections: Iterable[Connection | tuple[str, str] | str],
        *,
        record: Sequence[str] = (),
        gs_order: Sequence[str] | None = None,
        log_categories: Sequence[str] | None = None,
    ):
        self.system: System = build_system(units, connections, gs_order)
        sysm = self.system
        connected = set(sysm.outputs) | set(sysm.input_source)
        extra: list[str] = []
        for key in record:
            ref = sysm.resolve(key)
            if ref.type not in ("Real", "Integer", "Boolean", "Enumeration"):
                raise ValueError(f"cannot record {key!r}: type {ref.type} is not numeric")
            if key not in connected and key not in extra:
                extra.append(key)
        self.record: tuple[str, ...] = tuple(extra)
        if isinstance(log_categories, str):
            raise ValueError(f"log_categories must be a sequence of names, got {log_categories!r}")
        self.log_categories = None if log_categories is None else tuple(log_categories)

        seen: dict[str, str] = {}
        for unit, md in zip(sysm.units, sysm.model_descriptions, strict=True):
            path = str(Path(unit.fmu).resolve())
            if md.coSimulation.canBeInstantiatedOnlyOncePerProcess and path in seen:
                raise ValueError(
                    f"units {seen[path]!r} and {unit.name!r} use {unit.fmu}, which can be "
                    "instantiated only once per process"
                )
            seen.setdefault(path, unit.name)

        #: the SSP package the master was made from (:meth:`from_ssp`), else None
        self.ssp: SspPackage | None = None
        tmp, remove = temporary_folder("cosim_master_")  # removed on SIGTERM too
        self._tmp = str(tmp)
        self._finalizer = weakref.finalize(self, remove)
        self._unzipdirs: list[str] = []
        extracted: dict[str, str] = {}
        for i, unit in enumerate(sysm.units):
            path = str(Path(unit.fmu).resolve())
            if path not in extracted:
                extracted[path] = extract(path, unzipdir=Path(self._tmp, f"{i}_{unit.name}"))
            self._unzipdirs.append(str(extracted[path]))

    @classmethod
    def from_ssp(
        cls,
        path: str | Path,
        parameter_set: str | Sequence[str] | None = None,
        *,
        variant: str | None = None,
        fmus: Mapping[str, str | Path] | None = None,
        record: Sequence[str] | None = None,
        gs_order: Sequence[str] | None = None,
        log_categories: Sequence[str] | None = None,
    ) -> Master:
        """A master of the system an SSD of an SSP 1.0 package describes (:mod:`.ssp`).

        The SSD's components become units, its connections the master's connections; the
        start values are the FMUs' own, replaced by the SSD's parameter bindings as SSP 1.0
        applies them (every binding of a component, in order, later ones winning) or by the
        named parameter set(s). A value given in another unit than its FMU variable's is
        converted into it (units defined in the ``.ssv`` or the ``.ssd``: ``Omega0 = 51.756``
        in rpm is set as 5.42 rad/s); a connection between FMU variables of different units of
        one dimension converts the value on the way (:mod:`.connections`). Units are compared
        by their definitions, not their names. The SSD's default experiment is :attr:`ssp`
        (``stop_time``, ``step``).

        Parameters
        ----------
        path : path
            The ``.ssp`` archive, an SSP folder, or an ``.ssd`` file in such a folder.
        parameter_set : str or sequence of str, optional
            None: the SSD's bindings. Names: those parameter sets of the package, applied in
            the order given, instead of the bindings (SSP's named sets as Ecos's
            ``--parameterSet`` applies them). ``()``: none (the FMUs' start values).
        variant : str, optional
            The SSD of the package (its name or file name; default ``SystemStructure.ssd``).
        fmus : mapping, optional
            Component name -> another FMU file to use in its place (it must have the
            component's connectors and the parameters the applied sets give).
        record : sequence of str, optional
            Extra ``"unit.var"`` to record (default: every output connector).
        gs_order, log_categories
            As for :class:`Master`.

        Returns
        -------
        Master
            The master; :attr:`ssp` is the SSD read. Close it (or use it as a context manager)
            to remove the extracted files.

        Raises
        ------
        SspError
            For an invalid package, an unknown variant, parameter set or component, connected
            connectors of different dimensions, a parameter the FMU does not have, or one
            given in a unit that is not defined or not of the dimension of the FMU variable's
            (the message names the parameter, the unit and the dimension expected).
        ValueError
            For connected FMU variables of different dimensions (naming the connection, both
            units and their dimensions), a connection of which only one end declares a unit
            (other than "1") and that does not suppress unit conversion (naming both ends, their
            FMUs and the unit), and the errors of :class:`Master`.
        """
        tmp, remove = temporary_folder("cosim_ssp_")  # removed on SIGTERM too
        try:
            package = read_ssp(path, unpack_to=Path(tmp) / "package", variant=variant)
            values = package.parameters(parameter_set)
            replaced = dict(fmus or {})
            for name in replaced:
                package.component(name)  # an unknown component is an error
            units = []
            for comp in package.components:
                fmu = Path(replaced.get(comp.name, package.fmu(comp.name)))
                # a packaged FMU is named by its path in the package, not the unpacked copy's
                shown = None if comp.name in replaced else f"{comp.source!r} of {Path(path).name}"
                start = _typed_values(comp.name, fmu, values[comp.name], shown)
                units.append(Unit(comp.name, fmu, start))
            _check_connected_units(package)
            if record is None:
                record = [
                    f"{c.name}.{k.name}"
                    for c in package.components
                    for k in c.connectors
                    if k.kind == "output"
                ]
            connections = [
                Connection(
                    f"{c.start_element}.{c.start_connector}",
                    f"{c.end_element}.{c.end_connector}",
                    convert_units=not c.suppress_unit_conversion,
                )
                for c in package.connections
            ]
            master = cls(
                units,
                connections,
                record=record,
                gs_order=gs_order,
                log_categories=log_categories,
            )
        except BaseException:
            remove()
            raise
        master.ssp = package
        weakref.finalize(master, remove)
        return master

    # -- lifecycle -------------------------------------------------------------------

    def close(self) -> None:
        """Remove the extracted FMUs."""
        self._finalizer()

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- public API ------------------------------------------------------------------

    @property
    def columns(self) -> tuple[str, ...]:
        """Field names of the result: time, connected outputs, connected inputs, record."""
        return ("time", *self.system.outputs, *self.system.input_source, *self.record)

    def run(
        self,
        stop_time: float,
        step: float | None = None,
        *,
        start_time: float = 0.0,
        scheme: Scheme = "jacobi",
        extrapolation: Extrapolation = "zoh",
        step_control: StepControl | None = None,
        progress: bool | None = None,
        exchange: ExchangeMode = "propagate",
        grid: Literal["float", "ns", "sum"] = "float",
    ) -> CosimResult:
        """Co-simulate from ``start_time`` to ``stop_time``.

        Parameters
        ----------
        stop_time : float
            End of the run.
        step : float, optional
            Fixed macro step (the last step is shortened to land on ``stop_time``); with
            ``step_control`` the first step (default ``step_control.h_init`` or ``h_max``).
        start_time : float
            Start of the run.
        scheme : {"jacobi", "gauss-seidel"}
            Coupling scheme of a macro step.
        extrapolation : {"zoh", "linear"}
            Inputs held over a step, or the mean of the line through the last two values.
        step_control : StepControl, optional
            Adaptive macro steps with rollback (every unit must be able to get and set its
            FMU state).
        progress : bool, optional
            tqdm bar (None: only on a terminal).
        exchange : {"propagate", "simple"}
            Exchange after a step: the dependency-ordered schedule, or libcosim's
            read-all-then-write-all.
        grid : {"float", "ns", "sum"}
            Communication points of a fixed-step run: ``start_time + k*step``, libcosim's
            integer-nanosecond grid, or ``t + step`` accumulated (Ecos, fmpy's SSP simulator).

        Returns
        -------
        CosimResult
            Trajectories at the communication points and how the run went. FMU failures
            never raise: see :attr:`CosimResult.failure`.

        Raises
        ------
        ValueError
            For bad arguments, naming the value, or a unit that cannot do what they ask
            (variable steps, rollback).
        """
        check_real("start_time", start_time)
        check_real("stop_time", stop_time, lower=start_time)
        check_choice("scheme", scheme, ("jacobi", "gauss-seidel"))
        check_choice("extrapolation", extrapolation, ("zoh", "linear"))
        check_choice("exchange", exchange, ("propagate", "simple"))
        check_choice("grid", grid, ("float", "ns", "sum"))
        if grid == "sum" and step_control is not None:
            raise ValueError("grid='sum' is for fixed-step runs, not with step_control")
        if grid == "ns":
            if step_control is not None:
                raise ValueError("grid='ns' is for fixed-step runs, not with step_control")
            if step is None or not (math.isfinite(step) and round(step * 1e9) >= 1):
                raise ValueError(f"grid='ns' needs a step of at least 1 ns, got {step!r}")
            for name, v in (("step", step), ("start_time", start_time)):
                if abs(round(v * 1e9) - v * 1e9) > 1e-6 + 1e-12 * abs(v) * 1e9:
                    raise ValueError(
                        f"grid='ns' needs a {name} that is a whole number of ns, got {v!r}"
                    )
        if step_control is None:
            if step is None:
                raise ValueError("a fixed-step run needs a step (or pass step_control)")
            check_real("step", step, lower=0.0)
        else:
            if not isinstance(step_control, StepControl):
                raise ValueError(f"step_control must be a StepControl, got {step_control!r}")
            if step is None:
                step = step_control.h_init or step_control.h_max
            if not step_control.h_min <= step <= step_control.h_max:
                raise ValueError(
                    f"initial step {step!r} outside [h_min, h_max] = "
                    f"[{step_control.h_min!r}, {step_control.h_max!r}]"
                )
        variable_steps = step_control is not None or not n_steps(stop_time - start_time, step)[1]
        for unit, md in zip(self.system.units, self.system.model_descriptions, strict=True):
            cs = md.coSimulation
            if step_control is not None and not cs.canGetAndSetFMUstate:
                raise ValueError(
                    f"step-size control needs rollback, but unit {unit.name!r} cannot get and "
                    "set its FMU state (canGetAndSetFMUstate=false)"
                )
            if variable_steps and not cs.canHandleVariableCommunicationStepSize:
                raise ValueError(
                    f"unit {unit.name!r} cannot handle variable communication step sizes; use "
                    "a fixed step that divides stop_time - start_time"
                )
        options = RunOptions(
            start_time=float(start_time),
            stop_time=float(stop_time),
            step=step,
            step_control=step_control,
            scheme=scheme,
            extrapolation=extrapolation,
            exchange=exchange,
            grid=grid,
            progress=progress,
        )
        return self._execute(options)

    def _execute(self, options: RunOptions) -> CosimResult:
        """One run on fresh instances (options checked by :meth:`run`)."""
        wall = _time.perf_counter()
        failure: FmuFailure | None = None
        t0, t_end = options.start_time, options.stop_time
        instances = Instances(self.system, self._unzipdirs, self.log_categories)
        bar = tqdm(
            total=t_end - t0,
            disable=None if options.progress is None else not options.progress,
            desc="co-simulation",
            unit="s(sim)",
            leave=False,
            bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} [{elapsed}<{remaining}]",
        )

        def show(t: float) -> None:
            bar.update(t - t0 - bar.n)

        run = Run(options, instances, self.record, show)
        try:
            run.set_up()
            if options.step_control is None:
                run_fixed(run)
            else:
                run_adaptive(run)
        except UnitFailure as f:
            failure = instances.describe(f)
            log.warning("co-simulation stopped: %s", failure)
        finally:
            bar.close()
            instances.release()
        stats = run.stats(_time.perf_counter() - wall)
        log.info(
            "co-simulation %s: %d accepted, %d rejected steps, %.3g s wall",
            "completed" if failure is None else "failed",
            stats.accepted,
            stats.rejected,
            stats.wall_time,
        )
        recorder = run.recorder
        data = recorder.table() if recorder is not None else _empty_table(self.columns)
        return CosimResult(
            data=data,
            stats=stats,
            failure=failure,
            log=tuple(instances.log),
            step_log=run.step_table(),
        )


def _typed_values(
    component: str, fmu: Path, values: Mapping[str, SspParameter], shown: str | None = None
) -> dict:
    """Start values of a component's parameters for its FMU's variables: an ``ssv:Enumeration``
    item name becomes its value, a Real given in another unit is converted into the
    variable's; a parameter the FMU does not have is an error (not silently ignored)."""
    md = read_fmu_description(f"component {component!r}", fmu, shown)
    variables = {v.name: v for v in md.modelVariables}
    defs = unit_definitions(md)
    out = {}
    for name, p in values.items():
        var = variables.get(name)
        if var is None:
            raise SspError(
                f"component {component!r}: {fmu.name} has no variable {name!r} (parameter set)"
            )
        value = p.value
        if p.type == "Enumeration":
            items = {item.name: int(item.value) for item in var.declaredType.items}
            if value not in items:
                raise SspError(
                    f"component {component!r}: {value!r} is not an item of {name} ({list(items)})"
                )
            value = items[value]
        elif p.type == "Real" and var.type == "Real":
            value = _in_variable_unit(component, fmu.name, p, variable_unit(var), defs)
        out[name] = value
    return out


def _in_variable_unit(
    component: str, fmu: str, p: SspParameter, unit: str | None, defs: Mapping[str, UnitDef]
) -> float:
    """A Real parameter's value in its FMU variable's unit (see :meth:`Master.from_ssp`; fmpy's
    reader has checked that ``unit`` is among the FMU's ``defs``). The definitions decide, not
    the names: a unit of the variable's name that the ``.ssv`` or ``.ssd`` defines otherwise
    than the FMU is converted; one of that name they leave undefined is taken as the FMU's."""
    value = float(p.value)
    if p.unit is None or (
        p.unit == unit and (p.unit_def is None or _same_unit(p.unit_def, defs[unit]))
    ):
        return value
    what = f"component {component!r}: parameter {p.name!r} = {value!r} given in {p.unit!r}"
    if unit is None:
        raise SspError(f"{what}, but {fmu} declares no unit for {p.name}: cannot convert it")
    if p.unit_def is None:
        raise SspError(f"{what}: unit {p.unit!r} is defined neither in its .ssv nor in the .ssd")
    target = defs[unit]
    try:
        conv = unit_conversion(p.unit_def, target)
    except UnitMismatch:
        raise SspError(
            f"{what} (dimension {p.unit_def.dimension}): {p.name} of {fmu} is in {unit!r}, a unit "
            f"of dimension {target.dimension}; not convertible"
        ) from None
    if conv.identity:
        return value
    log.info("%s: set as %r %s", what, conv(value), unit)
    return conv(value)


def _same_unit(a: UnitDef, b: UnitDef) -> bool:
    """Whether two unit definitions are the same unit (exponents, factor, offset; not names)."""
    return a.same_dimension(b) and (a.factor, a.offset) == (b.factor, b.offset)


def _check_connected_units(package: SspPackage) -> None:
    """Connected connectors must have units of one dimension (the values are converted between
    the FMUs' own units by the master, :mod:`.connections`)."""
    unit = {(c.name, k.name): k.unit for c in package.components for k in c.connectors}
    for con in package.connections:
        a = unit.get((con.start_element, con.start_connector))
        b = unit.get((con.end_element, con.end_connector))
        ua, ub = package.units.get(a), package.units.get(b)
        if a != b and ua is not None and ub is not None and not ua.same_dimension(ub):
            raise SspError(
                f"{package.file}: connection {con}: the connectors' units {a!r} (dimension "
                f"{ua.dimension}) and {b!r} (dimension {ub.dimension}) are of different "
                "dimensions"
            )


def _empty_table(columns: Sequence[str]) -> np.ndarray:
    """A result without rows (the run failed before the first communication point)."""
    return np.empty(0, dtype=np.dtype([(n, np.float64) for n in columns]))

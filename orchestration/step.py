"""One macro step ``t -> t + h`` of all units, then the exchange at ``t + h``.

Two coupling schemes, same interface (:meth:`JacobiStep.advance`):

* :class:`JacobiStep`: every unit steps with the inputs of ``t``;
* :class:`GaussSeidelStep`: units step one after the other (the system's Gauss-Seidel order);
  a unit whose source has already stepped receives that source's fresh value at ``t + h``.

Extrapolation of the inputs over the step: ``"zoh"`` holds an input at its exchanged value;
``"linear"`` uses the line through the last two exchanged values (Gauss-Seidel: the line
between ``t`` and the fresh value for already-stepped sources). FMI 2.0 units hold inputs
constant over a step unless they can interpolate, so the step gives the *mean* of that line
over the step (its value at ``t + h/2``), which reproduces its integral exactly: a
second-order coupling.

A step never decides its own size: :mod:`.fixed` and :mod:`.adaptive` do.
"""

from __future__ import annotations

import numpy as np

from drillstring.orchestration.exchange import Exchange
from drillstring.orchestration.instances import Instances

__all__ = ["JacobiStep", "GaussSeidelStep", "macro_step"]


class JacobiStep:
    """Jacobi macro step: all units step from the same inputs.

    Parameters
    ----------
    instances : Instances
        The units of the run.
    exchange : Exchange
        Their exchange (its ``y`` holds the values at the current communication point).
    linear : bool
        Linear extrapolation of the inputs (else zero-order hold).
    """

    def __init__(self, instances: Instances, exchange: Exchange, linear: bool) -> None:
        self.linear = linear
        self._items = instances.items
        self._fail = instances.fail
        self._exchange = exchange.exchange
        self._step_xops = exchange.step_xops
        self._set_inputs = exchange.set_inputs
        self._input_ops = [op for op in exchange.input_ops if op is not None]
        self.y = exchange.y
        self.converts = exchange.converts

    def _held(self, h: float, y_prev: np.ndarray, h_prev: float) -> np.ndarray:
        """Mean over [t, t+h] of the line through the values at t - h_prev and t."""
        y = self.y
        return y + (y - y_prev) * (0.5 * h / h_prev)

    def advance(
        self, t: float, h: float, y_prev: np.ndarray | None, h_prev: float, nsp: int
    ) -> None:
        """Step every unit from ``t`` to ``t + h`` and exchange at ``t + h``.

        Parameters
        ----------
        t, h : float
            Communication point and macro step.
        y_prev : numpy.ndarray or None
            Exchanged values at ``t - h_prev`` for linear extrapolation (None: hold).
        h_prev : float
            The previous macro step.
        nsp : int
            fmi2DoStep's noSetFMUStatePriorToCurrentPoint (0 when a rollback may follow).
        """
        if self.linear and y_prev is not None:
            held = self._held(h, y_prev, h_prev)
            for op in self._input_ops:
                self._set_inputs(op, held, t)
        for inst in self._items:
            st = inst.do_step(inst.comp, t, h, nsp)
            if st > 1:
                self._fail(inst, "fmi2DoStep", st, t, h)
        self._exchange(t + h, self._step_xops)


class GaussSeidelStep(JacobiStep):
    """Gauss-Seidel macro step: units step in turn, later ones see fresh outputs.

    Parameters
    ----------
    instances, exchange, linear
        As for :class:`JacobiStep`; the order is ``instances.system.gs_order``.
    """

    def __init__(self, instances: Instances, exchange: Exchange, linear: bool) -> None:
        super().__init__(instances, exchange, linear)
        sysm = instances.system
        links = [(t.split(".", 1)[0], s.split(".", 1)[0]) for t, s in sysm.input_source.items()]
        order = [instances[i].name for i in sysm.gs_order]
        # (unit, its inputs, reads a source stepped before it, its outputs, feeds a later unit)
        self._plan = []
        for k, i in enumerate(sysm.gs_order):
            name = order[k]
            fresh = any(t == name and s in order[:k] for t, s in links)
            feeds_later = any(s == name and t in order[k + 1 :] for t, s in links)
            self._plan.append(
                (instances[i], exchange.input_ops[i], fresh, exchange.output_ops[i], feeds_later)
            )

    def advance(
        self, t: float, h: float, y_prev: np.ndarray | None, h_prev: float, nsp: int
    ) -> None:
        """Step the units in turn from ``t`` to ``t + h`` and exchange at ``t + h``.

        Parameters are those of :meth:`JacobiStep.advance`.
        """
        y = self.y
        held = self._held(h, y_prev, h_prev) if self.linear and y_prev is not None else None
        z = y.copy() if held is None else held
        for inst, in_op, fresh, out_op, feeds_later in self._plan:
            if in_op is not None and (fresh or held is not None):
                self._set_inputs(in_op, z, t)
            st = inst.do_step(inst.comp, t, h, nsp)
            if st > 1:
                self._fail(inst, "fmi2DoStep", st, t, h)
            if feeds_later:
                st = out_op.fn(inst.comp, out_op.vr, out_op.n, out_op.buf)
                if st > 1:
                    self._fail(inst, "fmi2GetReal", st, t + h, None)
                if self.linear:  # mean of the line from y(t) to the fresh y(t+h)
                    z[out_op.idx] = 0.5 * (y[out_op.idx] + out_op.view)
                else:
                    z[out_op.idx] = out_op.view
        self._exchange(t + h, self._step_xops)


def macro_step(
    instances: Instances, exchange: Exchange, scheme: str, extrapolation: str
) -> JacobiStep:
    """The macro step of ``scheme`` (``"jacobi"`` or ``"gauss-seidel"``).

    Parameters
    ----------
    instances : Instances
        The units of the run.
    exchange : Exchange
        Their exchange.
    scheme : str
        ``"jacobi"`` or ``"gauss-seidel"``.
    extrapolation : str
        ``"zoh"`` or ``"linear"``.

    Returns
    -------
    JacobiStep or GaussSeidelStep
        The step.
    """
    cls = GaussSeidelStep if scheme == "gauss-seidel" else JacobiStep
    return cls(instances, exchange, extrapolation == "linear")

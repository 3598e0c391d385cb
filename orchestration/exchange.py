"""The exchange at a communication point: outputs read, inputs written, in schedule order.

:class:`Exchange` carries out the schedule of :mod:`.schedule` on the units of a run. The
connected outputs live in one value vector ``y``, laid out in schedule order so that every
batched fmi2GetReal of a round writes one contiguous slice of ``y`` (its ctypes buffer aliases
``y``: no copy); every batched fmi2SetReal gathers its source values from ``y``.

Two exchanges after a macro step (the initialization always uses the schedule):

* ``"propagate"``: the schedule, so an output with direct feedthrough is read only after its
  inputs received their values at the new communication point;
* ``"simple"``: every connected output is read once, then all inputs are written (libcosim's
  ``fixed_step_algorithm``). A feedthrough output read this way was computed from the inputs
  its unit had during the step, so a signal through a feedthrough unit arrives one macro step
  late.

``y`` holds every output in its own FMU's unit; an input whose source has another unit of the
same dimension (:attr:`~.connections.System.conversions`) is given the converted value
(:class:`~drillstring.model.units.Conversion`), on every path that sets inputs.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence

import numpy as np

from drillstring.orchestration.instances import Instance, Instances, RealBatch

__all__ = ["Exchange"]


def _flat(op: RealBatch, idx: np.ndarray | None) -> tuple:
    """A batch as a flat tuple for the exchange loop (idx None: a get into y)."""
    return (op.fn, op.inst.comp, op.vr, op.n, op.buf, idx, op.view, op.inst, op.fname, op.conv)


def _convert(view: np.ndarray, conv: tuple) -> None:
    """Apply a set batch's unit conversions to its gathered source values, in place."""
    for j, c in conv:
        view[j] = c(view[j])


class Exchange:
    """Value vector and batched FMI calls of the exchange, built once per run.

    Parameters
    ----------
    instances : Instances
        The instantiated units of the run (their system gives the schedule).
    simple : bool
        After a step, read all outputs and then write all inputs (``"simple"``) instead of
        following the schedule (``"propagate"``).

    Attributes
    ----------
    y : numpy.ndarray
        The connected outputs' values of the last exchange.
    yidx : dict
        Connected output key -> position in ``y``.
    input_ops, output_ops : list of RealBatch or None
        Per unit, all its connected inputs (a set) and all its connected outputs (a get).
    converts : bool
        Some input is given a converted value (module docstring).
    """

    def __init__(self, instances: Instances, simple: bool) -> None:
        sysm = instances.system
        self.instances = instances
        self.converts = bool(sysm.conversions)
        src_of = sysm.input_source
        layout = [k for rnd in sysm.schedule for _, keys in rnd.gets for k in keys]
        self.yidx = yidx = {k: j for j, k in enumerate(layout)}
        self.y = np.zeros(len(layout))
        base = self.y.ctypes.data
        self.xops = []  # flat tuples for the hot loop; gets have idx None
        for rnd in sysm.schedule:
            for i, keys in rnd.gets:
                pos = yidx[keys[0]]
                buf = (ctypes.c_double * len(keys)).from_address(base + 8 * pos)
                op = self._batch(instances[i], True, keys, range(pos, pos + len(keys)), buf)
                self.xops.append(_flat(op, None))
            for i, keys in rnd.sets:
                op = self._batch(instances[i], False, keys, [yidx[src_of[k]] for k in keys])
                self.xops.append(_flat(op, op.idx))
        self.step_xops = self.xops
        if simple:
            gets = [op for op in self.xops if op[5] is None]
            self.step_xops = gets + [op for op in self.xops if op[5] is not None]

        self.input_ops: list[RealBatch | None] = []
        self.output_ops: list[RealBatch | None] = []
        for inst in instances:
            ins = [k for k in src_of if k.split(".", 1)[0] == inst.name]
            outs = [k for k in sysm.outputs if k.split(".", 1)[0] == inst.name]
            self.input_ops.append(
                self._batch(inst, False, ins, [yidx[src_of[k]] for k in ins]) if ins else None
            )
            self.output_ops.append(
                self._batch(inst, True, outs, [yidx[k] for k in outs]) if outs else None
            )

    def _batch(self, inst: Instance, get: bool, keys: Sequence[str], idx, buf=None) -> RealBatch:
        sysm = self.instances.system
        vrs = [sysm.resolve(k).vr for k in keys]
        conv = () if get else [(j, sysm.conversions[k]) for j, k in enumerate(keys)
                               if k in sysm.conversions]  # fmt: skip
        return RealBatch(inst, get, vrs, idx, buf, conv)

    def exchange(self, t: float, ops: list | None = None) -> None:
        """Read outputs into ``y`` and write inputs from it at communication point ``t``.

        Parameters
        ----------
        t : float
            The communication point (for failure reports).
        ops : list, optional
            The batches in order: default the schedule (every input fresh at ``t``);
            :attr:`step_xops` is the exchange after a step.
        """
        take = self.y.take
        for fn, comp, vr, n, buf, idx, view, inst, fname, conv in self.xops if ops is None else ops:
            if idx is not None:  # a set: gather its source values from y
                take(idx, out=view)
                if conv:
                    _convert(view, conv)
            st = fn(comp, vr, n, buf)
            if st > 1:
                self.instances.fail(inst, fname, st, t, None)

    def set_inputs(self, op: RealBatch, values: np.ndarray, t: float) -> None:
        """Write one unit's inputs.

        Parameters
        ----------
        op : RealBatch
            The unit's batch of inputs (from :attr:`input_ops`).
        values : numpy.ndarray
            Source values, laid out like ``y``.
        t : float
            Communication point (for failure reports).
        """
        values.take(op.idx, out=op.view)
        if op.conv:
            _convert(op.view, op.conv)
        st = op.fn(op.inst.comp, op.vr, op.n, op.buf)
        if st > 1:
            self.instances.fail(op.inst, op.fname, st, t, None)

    def reset_inputs(self, t: float) -> None:
        """Write every unit's connected inputs from ``y`` (after a rollback).

        Parameters
        ----------
        t : float
            The communication point rolled back to.
        """
        for op in self.input_ops:
            if op is not None:
                self.set_inputs(op, self.y, t)

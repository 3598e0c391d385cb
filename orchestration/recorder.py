"""Rows of a run, one per communication point: time, exchanged values, recorded variables."""

from __future__ import annotations

import ctypes
from collections.abc import Sequence

import numpy as np

from drillstring.orchestration.exchange import Exchange
from drillstring.orchestration.instances import VR, Instances

__all__ = ["Recorder"]


class Recorder:
    """Records the exchanged values and the extra variables at every communication point.

    Parameters
    ----------
    instances : Instances
        The units of the run.
    exchange : Exchange
        Their exchange (the recorded ``y``).
    record : sequence of str
        Extra ``"unit.var"`` (Real, Integer, Boolean, Enumeration) read at each point,
        batched by unit and type.
    """

    def __init__(self, instances: Instances, exchange: Exchange, record: Sequence[str]) -> None:
        sysm = instances.system
        self.instances = instances
        self.exchange = exchange
        self.record_keys = tuple(record)
        self.y = exchange.y
        ny = len(self.y)
        self.n_cols = 1 + ny + len(self.record_keys)
        self.extra_ops: list[tuple] = []
        groups: dict[tuple[int, str], list[tuple[int, int]]] = {}
        for j, key in enumerate(self.record_keys):
            ref = sysm.resolve(key)
            kind = ref.type if ref.type in ("Real", "Boolean") else "Integer"
            groups.setdefault((ref.unit, kind), []).append((ref.vr, 1 + ny + j))
        for (i, kind), items in groups.items():
            inst = instances[i]
            fn = {"Real": inst.get_real, "Integer": inst.get_integer, "Boolean": inst.get_boolean}
            ctype = ctypes.c_double if kind == "Real" else ctypes.c_int
            n = len(items)
            buf = (ctype * n)()
            cols = np.array([c for _, c in items], dtype=np.intp)
            vrs = (VR * n)(*[v for v, _ in items])
            self.extra_ops.append((fn[kind], inst, vrs, n, buf, np.ctypeslib.as_array(buf), cols))
        self.rows = np.empty((256, self.n_cols))
        self.n = 0

    def reserve(self, n_rows: int) -> None:
        """Make room for exactly ``n_rows`` rows in all (no growth while they are recorded).

        Parameters
        ----------
        n_rows : int
            Total number of rows, those already recorded included.
        """
        rows = np.empty((n_rows, self.n_cols))
        rows[: self.n] = self.rows[: self.n]
        self.rows = rows

    def record(self, t: float) -> None:
        """Append the row of a communication point.

        Parameters
        ----------
        t : float
            The communication point (``y`` holds its exchanged values).
        """
        k = self.n
        if k == len(self.rows):
            self.rows = np.concatenate([self.rows, np.empty_like(self.rows)])
        row = self.rows[k]
        row[0] = t
        row[1 : 1 + len(self.y)] = self.y
        for fn, inst, vrs, n, buf, view, cols in self.extra_ops:
            st = fn(inst.comp, vrs, n, buf)
            if st > 1:
                self.instances.fail(inst, "fmi2Get (recorded variables)", st, t, None)
            row[cols] = view
        self.n = k + 1

    def times(self) -> np.ndarray:
        """The communication points recorded so far.

        Returns
        -------
        numpy.ndarray
            1-D view (not a copy) of the time column, one entry per recorded row.
        """
        return self.rows[: self.n, 0]

    def table(self) -> np.ndarray:
        """The rows recorded so far as a structured array (a copy).

        Returns
        -------
        numpy.ndarray
            One row per communication point, float64 fields ``time``, the connected outputs
            (``"unit.var"``), the connected inputs (the value of their source, converted to the
            input's unit where the units differ) and the recorded variables.
        """
        sysm = self.instances.system
        names = ("time", *sysm.outputs, *sysm.input_source, *self.record_keys)
        out = np.empty(self.n, dtype=np.dtype([(n, np.float64) for n in names]))
        if self.n == 0:
            return out
        rows = self.rows[: self.n]
        yidx = self.exchange.yidx
        ny = len(self.y)
        out["time"] = rows[:, 0]
        for k in sysm.outputs:
            out[k] = rows[:, 1 + yidx[k]]
        for k, s in sysm.input_source.items():
            conv = sysm.conversions.get(k)
            out[k] = rows[:, 1 + yidx[s]] if conv is None else conv(rows[:, 1 + yidx[s]])
        for j, k in enumerate(self.record_keys):
            out[k] = rows[:, 1 + ny + j]
        return out

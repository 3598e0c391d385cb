"""The sampled control laws, compiled: switch-on state, output and update of each law kind.

Plain Python in the subset numba compiles (``jit_for``), so the controller FMUs, the compiled
sampled loop and a Python caller run the same code. A law reads its parameters from the block
(``LP`` entries of :mod:`~drillstring.model.digital.layout`) and keeps its state as a tuple of
:data:`~drillstring.model.digital.layout.N_LX` floats. The measurements are those of
:class:`drillstring.model.laws.Measurement`, in the scaled perturbation form of (9)-(10): table
angle and speed, string-torque deviation ``theta - phi``, bit angle and speed.

The laws (their meaning, tunings and sources: ``docs/controllers.md``):

* ``LAW_PI``: ``R - R0 = R_ff + kp*e + ki*I``, ``e = -dtheta - z_gain*y``, ``y`` the string torque
  high-pass and low-pass filtered (``z_gain = 0``: the plain speed PI); the integral by forward
  Euler with optional anti-windup (back-calculation or conditional integration), both filters
  discretised exactly for the torque held over the sample;
* ``LAW_AFFINE``: the paper's state feedback (29)-(31), ``R - R0 = R_ff + F x`` with the
  references latched at switch-on (:func:`~drillstring.model.control.switch_on_references`),
  evaluated by :func:`~drillstring.model.control.feedback_torque`, plus ``g`` times the measured
  string torque's deviation from steady drilling (``torque + K0``; ``g = 0``, the default, is
  the paper's law; the string design of ``docs/controllers.md``, "A design that holds on the
  string"); optionally the bit-angle state is held while the top drive saturates, so that
  revolutions lost there are not made up after;
* ``LAW_NONE``: the feed-forward R_ff alone.
"""

from __future__ import annotations

import math

from drillstring.model.control import feedback_torque, switch_on_references
from drillstring.model.digital.layout import (
    AF_F,
    AF_G,
    AF_HOLD,
    AF_K0,
    AF_LATCH,
    AF_PHIREF,
    AF_SAT,
    AF_TWISTREF,
    AF_X1,
    AW_BACK,
    AW_COND,
    B_LAW,
    B_LP,
    B_LX,
    LAW_AFFINE,
    LAW_PI,
    LP_RFF,
    PI_AW,
    PI_I,
    PI_KI,
    PI_KP,
    PI_TT,
    PI_WHP,
    PI_WLP,
    PI_Y,
    PI_Z,
    PI_ZGAIN,
    SAT_FREEZE,
)
from drillstring.model.kernel.jit import jit_for

inline = jit_for(__name__, inline=True)

__all__ = ["law_output", "law_start", "law_state", "law_update", "preset"]


@inline
def preset(kp: float, ki: float, e: float) -> float:
    """The integral that makes ``kp*e + ki*I = 0``: bumpless transfer of a PI law (0 without
    an integrator, ``ki = 0``)."""
    return -kp * e / ki if ki > 0.0 else 0.0


@inline
def law_state(b):
    """The law's state as it is stored in the block (``LX``)."""
    return (b[B_LX], b[B_LX + 1], b[B_LX + 2], b[B_LX + 3])


@inline
def law_start(b, theta, dtheta, torque, phi, dphi):
    """The law's state at switch-on from the measurements there (bumpless for each law).

    PI: the integral preset for a continuous torque (``ki*I = -kp*e`` with ``e = -dtheta``),
    the high-pass at rest on the current torque, the low-pass at 0. Affine: the references of
    the latch mode (``docs/model.md``, "Bumpless switch-on").
    """
    kind = int(b[B_LAW])
    if kind == LAW_PI:
        return (preset(b[B_LP + PI_KP], b[B_LP + PI_KI], -dtheta), torque, 0.0, 0.0)
    if kind == LAW_AFFINE:
        phi_ref, twist_ref = switch_on_references(
            int(b[B_LP + AF_LATCH]), phi, theta, b[B_LP + AF_K0]
        )
        return (phi_ref, twist_ref, 0.0, 0.0)
    return (0.0, 0.0, 0.0, 0.0)


@inline
def _gain(b):
    p = B_LP + AF_F
    return (b[p], b[p + 1], b[p + 2], b[p + 3])


@inline
def law_output(b, x, theta, dtheta, torque, phi, dphi):
    """R - R0 the law commands for the state ``x`` and the measurements (pure)."""
    kind = int(b[B_LAW])
    R_ff = b[B_LP + LP_RFF]
    if kind == LAW_PI:
        e = -dtheta - b[B_LP + PI_ZGAIN] * x[PI_Y]
        return R_ff + b[B_LP + PI_KP] * e + b[B_LP + PI_KI] * x[PI_I]
    if kind == LAW_AFFINE:
        phi_ref = x[AF_PHIREF]
        if x[AF_HOLD] != 0.0:
            phi_ref = phi - x[AF_X1]
        r = feedback_torque(
            0.0, phi, dphi, theta, dtheta, _gain(b), b[B_LP + AF_K0], R_ff, 0.0, phi_ref,
            x[AF_TWISTREF],
        )  # fmt: skip
        g = b[B_LP + AF_G]
        if g != 0.0:  # the string torque's deviation from steady drilling (-K0), fed back
            r = r + g * (torque + b[B_LP + AF_K0])
        return r
    return R_ff


@inline
def law_update(b, x, theta, dtheta, torque, phi, dphi, Ts, r_cmd, r_lim):
    """The state one sample period ``Ts`` later, the measurements held over it.

    ``r_cmd`` is what the law commanded at the start of the period and ``r_lim`` what the top
    drive made of it (its limits; equal when nothing limited it): the anti-windup and the
    saturation behaviour of the affine law act only when they differ.
    """
    kind = int(b[B_LAW])
    if kind == LAW_PI:
        ki = b[B_LP + PI_KI]
        integral, z, y = x[PI_I], x[PI_Z], x[PI_Y]
        e = -dtheta - b[B_LP + PI_ZGAIN] * y
        aw = int(b[B_LP + PI_AW])
        if r_lim == r_cmd or ki <= 0.0:
            integral = integral + Ts * e
        elif aw == AW_BACK:
            integral = integral + Ts * (e + (r_lim - r_cmd) / (ki * b[B_LP + PI_TT]))
        elif aw == AW_COND:
            # integrate only when the error drives the command back into the range
            if (r_cmd > r_lim and e < 0.0) or (r_cmd < r_lim and e > 0.0):
                integral = integral + Ts * e
        else:
            integral = integral + Ts * e
        hp = torque - z
        a_hp = -math.expm1(-b[B_LP + PI_WHP] * Ts)
        a_lp = -math.expm1(-b[B_LP + PI_WLP] * Ts)
        return (integral, z + a_hp * (torque - z), y + a_lp * (hp - y), 0.0)
    if kind == LAW_AFFINE:
        if int(b[B_LP + AF_SAT]) != SAT_FREEZE:
            return x
        phi_ref, twist_ref, x1, hold = x[AF_PHIREF], x[AF_TWISTREF], x[AF_X1], x[AF_HOLD]
        if r_lim != r_cmd:
            if hold == 0.0:
                return (phi_ref, twist_ref, phi - phi_ref, 1.0)
            return x
        if hold != 0.0:  # the saturation ended: the reference moves so that x1 goes on from x1
            return (phi - x1, twist_ref, 0.0, 0.0)
        return x
    return x

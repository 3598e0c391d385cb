"""The float64 blocks are laid out from tables: no two slots overlap, every declared parameter of
a controller part has its slot, and the part's ``pack`` writes it there."""

from __future__ import annotations

import math
import re

import pytest

from drillstring.model import native
from drillstring.model.control import AffineFeedback
from drillstring.model.digital.controller import DigitalController, OperatingPoint
from drillstring.model.digital.layout import BLOCK, SECTIONS, slot_names, state_offsets
from drillstring.model.laws import (
    AFFINE_PARAMS,
    AFFINE_STATE,
    FEED_FORWARD_PARAMS,
    LAW_AFFINE,
    LAW_NONE,
    LAW_PI,
    LAW_SLOTS,
    PI_PARAMS,
    PI_STATE,
    FeedForward,
    Law,
    SampledAffine,
    SpeedPI,
    ZTorque,
)
from drillstring.model.sensing import FRAME, SENSING_SLOTS, Sensing
from drillstring.model.tables import Parameter, block_layout, parameter_slots
from drillstring.model.timing import TIMING_SLOTS, Timing
from drillstring.model.topdrive import TOP_DRIVE_SLOTS, TopDrive

#: Every layout of a float64 block the compiled code reads.
LAYOUTS = {
    "BLOCK": BLOCK,
    "LAW_SLOTS": LAW_SLOTS,
    "FEED_FORWARD_PARAMS": FEED_FORWARD_PARAMS,
    "PI_PARAMS": PI_PARAMS,
    "AFFINE_PARAMS": AFFINE_PARAMS,
    "PI_STATE": PI_STATE,
    "AFFINE_STATE": AFFINE_STATE,
    "TOP_DRIVE_SLOTS": TOP_DRIVE_SLOTS,
    "SENSING_SLOTS": SENSING_SLOTS,
    "FRAME": FRAME,
    "TIMING_SLOTS": TIMING_SLOTS,
    "PLANT": native.PLANT,
}
#: The law kinds' parameter and state layouts, by the law's KIND.
KIND_PARAMS = {LAW_NONE: FEED_FORWARD_PARAMS, LAW_PI: PI_PARAMS, LAW_AFFINE: AFFINE_PARAMS}
KIND_STATE = {LAW_PI: PI_STATE, LAW_AFFINE: AFFINE_STATE}
POINT = OperatingPoint(omega0=5.0, R0=4.0, rho=5.0)
#: The parts other than the law, and their sections.
PART_SECTIONS = ((TopDrive, "top_drive"), (Sensing, "sensing"), (Timing, "timing"))


def _overlaps(layout) -> list[str]:
    """Entries of ``layout`` that overlap another or leave the block, and the gaps."""
    spans = sorted((getattr(layout, name), size, name) for name, size in layout.SLOTS)
    found, end = [], 0
    for at, size, name in spans:
        if at < end:
            found.append(f"{name} at {at} overlaps the entry before it (ends at {end})")
        elif at > end:
            found.append(f"a gap before {name} ({end}..{at})")
        end = max(end, at + size)
    if end != layout.size:
        found.append(f"the entries end at {end}, the layout's size is {layout.size}")
    return found


def test_no_two_slots_of_a_layout_overlap():
    found = {name: _overlaps(layout) for name, layout in LAYOUTS.items()}
    sizes = dict(BLOCK.SLOTS)
    p_size, x_size = dict(LAW_SLOTS.SLOTS)["p"], dict(LAW_SLOTS.SLOTS)["x"]
    nested = [
        *(f"section {n}: {part.size} slots in an entry of {sizes[n]}"
          for n, part in SECTIONS.items() if part.size != sizes[n]),
        *(f"law kind {k}: {lay.size} parameters in {p_size} slots"
          for k, lay in KIND_PARAMS.items() if lay.size > p_size),
        *(f"law kind {k}: {lay.size} states in {x_size} slots"
          for k, lay in KIND_STATE.items() if lay.size > x_size),
    ]  # fmt: skip
    assert {k: v for k, v in found.items() if v} == {} and nested == []


def test_the_overlap_check_sees_an_overlap():
    """The check above on a layout with two entries at the same offset (hand-made)."""
    bad = block_layout("Bad", (("a", 2), ("b", 1)))._replace(b=1)
    assert _overlaps(bad) == ["b at 1 overlaps the entry before it (ends at 2)",
                              "the entries end at 2, the layout's size is 3"]  # fmt: skip


def _slot(part: type, name: str) -> int | None:
    """The block offset of parameter ``name`` of the controller part ``part`` (None: none)."""
    match = re.fullmatch(r"(\w+)\[(\d+)\]", name)
    entry, index = (match.group(1), int(match.group(2)) - 1) if match else (name, 0)
    if issubclass(part, Law):
        if name == "t_on":  # the switch-on is the controller's own entry
            return BLOCK.t_on
        base, layout = BLOCK.law + LAW_SLOTS.p, KIND_PARAMS[part.KIND]
    else:
        key = next(k for c, k in PART_SECTIONS if issubclass(part, c))
        base, layout = getattr(BLOCK, key), SECTIONS[key]
    at = getattr(layout, entry, None)
    return None if at is None else base + at + index


PARTS = (SpeedPI, ZTorque, SampledAffine, FeedForward, TopDrive, Sensing, Timing)


def test_every_parameter_of_every_part_has_a_slot():
    missing = [f"{part.__name__}.{p.name}" for part in PARTS for p in part.PARAMETERS
               if _slot(part, p.name) is None]  # fmt: skip
    assert missing == []


def test_an_undeclared_parameter_has_no_slot():
    """The look-up above fails for a parameter added to a table without its slot."""

    class Wider(Timing):
        PARAMETERS = (*Timing.PARAMETERS, Parameter("jitter", "time", "not in the block"))

    assert _slot(Wider, "jitter") is None and _slot(Wider, "latency") == BLOCK.timing + 1


def _controllers() -> list[DigitalController]:
    """Controllers whose numeric parameters are all different and nonzero."""
    drive = TopDrive(R_min=-7.5, R_max=8.25, rate=31.0, lag=0.0125, P_max=47.0, omega_min=-1.5,
                     omega_max=9.75)  # fmt: skip
    sensing = Sensing(downhole="telemetry", period=0.035, latency=0.07, noise_phi=0.011,
                      noise_dphi=0.013, seed=17, torque="motor")  # fmt: skip
    timing = Timing(period=0.02, latency=0.04)
    feedback = AffineFeedback((1.25, -2.5, 0.375, 0.625), -1.75, 0.3, 0.45, "angle")
    laws = [
        SpeedPI(kp=2.5, ki=1.25, R_ff=0.6, t_on=0.15, tracking_time=0.7),
        ZTorque(kp=3.5, ki=0.75, z_gain=0.8, omega_hp=0.35, omega_lp=9.5, R_ff=0.2, t_on=0.05,
                tracking_time=0.9),
        SampledAffine(feedback, on_saturation="freeze-angle", torque_gain=0.4),
        FeedForward(R_ff=0.55, t_on=0.25),
    ]  # fmt: skip
    return [DigitalController(law, drive, sensing, timing=timing) for law in laws]


@pytest.mark.parametrize("controller", _controllers(), ids=lambda c: type(c.law).__name__)
def test_pack_writes_each_number_into_its_slot(controller):
    b = controller.block(POINT)
    wrong = []
    for part in (controller.law, controller.top_drive, controller.sensing, controller.timing):
        values = part.values()
        for p in part.PARAMETERS:
            value = values[p.name]
            if p.choices or not math.isfinite(value):
                continue
            at = _slot(type(part), p.name)
            if b[at] != value:
                wrong.append(f"{type(part).__name__}.{p.name} = {value!r}, block[{at}] = {b[at]!r}")
    assert wrong == []


def test_the_state_and_the_names_of_the_block():
    names = slot_names()
    assert len(names) == BLOCK.size
    state = {names[k] for k in state_offsets()}
    assert state == {"active", "r_cmd", "r_app", "saturated", "n_sat", "n_samples", "law.x",
                     "top_drive.R", "top_drive.t", "top_drive.init", "top_drive.dt",
                     *(f"sensing.{n}" for n in SENSING_SLOTS.STATE),
                     *(f"timing.{n}" for n in TIMING_SLOTS.STATE)}  # fmt: skip
    assert "sensing.frames" in state and "timing.pending" in state and "law.p" not in state
    b = _controllers()[0].block(POINT)
    assert b[BLOCK.timing + TIMING_SLOTS.period] == 0.02


def test_block_layout_is_its_table():
    layout = block_layout("L", (("a", 1), ("b", 3), ("c", 2)), state=("b",))
    assert (layout.a, layout.b, layout.c, layout.size) == (0, 1, 4, 6)
    assert layout.SLOTS == (("a", 1), ("b", 3), ("c", 2)) and layout.STATE == ("b",)
    for table, message in [
        ((("a", 1), ("a", 2)), "entry 'a' is repeated"),
        ((("a", 0),), "entry 'a' has size 0"),
        ((("a", 1.0),), "entry 'a' has size 1.0"),
        ((("F[1]", 1),), "'F\\[1\\]' is not a name"),
        ((("size", 1),), "'size' is not a name"),
    ]:
        with pytest.raises(ValueError, match=message):
            block_layout("L", table)
    with pytest.raises(ValueError, match=r"state entries \['z'\]"):
        block_layout("L", (("a", 1),), state=("z",))


def test_parameter_slots_of_a_table():
    table = [Parameter("k", "1", ""), *(Parameter(f"F[{i}]", "1", "") for i in (1, 2, 3)),
             Parameter("t_on", "time", "")]  # fmt: skip
    assert parameter_slots(table) == (("k", 1), ("F", 3), ("t_on", 1))
    assert parameter_slots(table, skip=("t_on",)) == (("k", 1), ("F", 3))
    with pytest.raises(ValueError, match="F\\[2\\]: the elements of F"):
        parameter_slots([Parameter("F[2]", "1", "")])

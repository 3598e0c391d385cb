"""The drill pipe as a distributed string: its parameters and its chain of N elements.

The paper's model (11)-(13) has one torsional mode: the pipe is a massless spring C between the
rotary table (inertia I2 = rho*I1) and the bit end (inertia I1, the bottom-hole assembly plus a
third of the pipe's polar inertia), and axially a massless spring K between the hook and the
bit-end mass M. ``docs/model.md``, "The distributed string", derives the wave equations of the
pipe in the paper's scaling; this module holds the one new torsional parameter and its axial
counterpart, and the lumped-mass chain of N equal elements that discretises them:

* ``kappa = I_pipe/I1``, the pipe's polar inertia in units of I1; the bit end is then the
  bottom-hole assembly alone, ``1 - kappa/3`` in units of I1, and the scaled torsional travel
  time of the pipe and its scaled impedance are both ``sqrt(kappa)``;
* ``axial_mass_ratio = M_pipe/M`` (mu), the pipe's mass in units of M; the axial bit end is
  ``1 - mu/3`` in units of M, the travel time ``sqrt(mu)/eta``. 0 (the default) keeps the axial
  spring massless, as in the paper: the paper's K is not the pipe's EA/L on the reference rig
  (``docs/reference_rig.md``), so distributing its mass there would describe no string.

Node 0 is the rotary table (torsion) or the hook (axial, its motion imposed), node N the bit.
With the ``"lumped"`` lumping each element's inertia is split half and half between its two
nodes; with the ``"paper"`` lumping (one element only) the pipe's third sits at the bit and the
spring is massless, which is exactly (11)-(13).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drillstring.model.params import KNOWN_PHYSICAL, PIPE_RIG, REFERENCE_PIPE_MASS, PhysicalParams
from drillstring.validation import check_choice, check_int, check_real

#: How the pipe's inertia is put on the nodes (``docs/model.md``, "The distributed string").
LUMPINGS = ("paper", "lumped")
#: The most elements a string may have; the stability of the explicit RK4 bounds N far lower for
#: the usual step (:func:`max_elements`), this bounds the memory of a mistyped number.
MAX_ELEMENTS = 4096

#: The reference rig's pipe (``docs/reference_rig.md``): 4008.9 m of 5-in 19.5 lb/ft pipe,
#: 0.09326 kg m^2 of polar inertia per metre (steel, 7850 kg/m^3), over I1 = 200 kg m^2.
REFERENCE_KAPPA = (
    7850.0
    * math.pi
    * (0.127**4 - 0.1086**4)
    / 32.0
    * (79.3e9 * math.pi * (0.127**4 - 0.1086**4) / 32.0 / 235.0)
    / 200.0
)


@dataclass(frozen=True)
class StringParams:
    """The pipe of the scaled model as a string of ``elements`` equal elements.

    Parameters
    ----------
    elements : int
        N, the number of elements (1 to :data:`MAX_ELEMENTS`).
    kappa : float
        Pipe polar inertia over I1, in [0, 3): the bit end keeps ``1 - kappa/3``.
    axial_mass_ratio : float
        Pipe mass over M, in [0, 3); 0 keeps the axial spring massless (the paper's).
    lumping : str
        ``"paper"`` (N = 1 only: massless spring, the pipe's third at the bit, eqs. (11)-(13)
        exactly) or ``"lumped"`` (each element's inertia half at each of its nodes). ``None``
        picks ``"paper"`` for one element and ``"lumped"`` otherwise.

    Raises
    ------
    ValueError
        A value out of its range, naming it; ``"paper"`` with more than one element; a lumped
        string without pipe inertia (its inner nodes would have none).
    """

    elements: int = 1
    kappa: float = REFERENCE_KAPPA
    axial_mass_ratio: float = 0.0
    lumping: str | None = None

    def __post_init__(self) -> None:
        n = check_int("StringParams.elements", self.elements, lower=1)
        if n > MAX_ELEMENTS:
            raise ValueError(
                f"StringParams.elements must be <= {MAX_ELEMENTS}, got {self.elements!r}"
            )
        object.__setattr__(self, "elements", n)
        for name in ("kappa", "axial_mass_ratio"):
            x = check_real(f"StringParams.{name}", getattr(self, name), lower=0.0, strict=False)
            if not x < 3.0:
                raise ValueError(
                    f"StringParams.{name} must be < 3 (the bit end keeps 1 - {name}/3), "
                    f"got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, x)
        lumping = self.lumping or ("paper" if n == 1 else "lumped")
        check_choice("StringParams.lumping", lumping, LUMPINGS)
        object.__setattr__(self, "lumping", lumping)
        if lumping == "paper" and n != 1:
            raise ValueError(
                f"StringParams: the 'paper' lumping has one element, got elements = {n}"
            )
        if lumping == "lumped" and n > 1 and self.kappa == 0.0:
            raise ValueError(
                "StringParams: a string of elements = "
                f"{n} needs pipe inertia, got kappa = {self.kappa!r}"
            )

    @property
    def is_paper(self) -> bool:
        """True for the paper's one-mode model (11)-(13)."""
        return self.lumping == "paper"

    @property
    def axial_distributed(self) -> bool:
        """True when the axial pipe has mass (a chain of N elements), not a massless spring."""
        return not self.is_paper and self.axial_mass_ratio > 0.0 and self.elements > 1

    @property
    def travel_time(self) -> float:
        """Scaled one-way travel time of the torsional wave along the pipe, sqrt(kappa)."""
        return math.sqrt(self.kappa)

    @property
    def impedance(self) -> float:
        """Scaled characteristic impedance of the pipe in torsion, sqrt(kappa) (units C*t*)."""
        return math.sqrt(self.kappa)


@dataclass(frozen=True)
class Chain:
    """Node inertias and element stiffnesses of one direction of the string (scaled).

    ``inertia[0]`` is the top node (rotary table, or the hook whose motion is imposed),
    ``inertia[-1]`` the bit; ``stiffness`` is the stiffness of each of the N equal elements.
    """

    inertia: np.ndarray
    stiffness: float

    @property
    def elements(self) -> int:
        """N, the number of elements."""
        return self.inertia.size - 1


def torsional_chain(string: StringParams, rho: float) -> Chain:
    """The torsional chain: table inertia rho, bit end 1 - kappa/3, pipe kappa, stiffness N.

    Parameters
    ----------
    string : StringParams
        The pipe.
    rho : float
        The table's inertia I2/I1, eq. (16).

    Returns
    -------
    Chain
        In units of I1 and C; the paper's lumping gives inertias (rho, 1) and stiffness 1.
    """
    n = string.elements
    if string.is_paper:
        return Chain(np.array([rho, 1.0]), 1.0)
    J = np.full(n + 1, string.kappa / n)
    J[0] = rho + string.kappa / (2 * n)
    J[-1] = (1.0 - string.kappa / 3.0) + string.kappa / (2 * n)
    return Chain(J, float(n))


def axial_chain(string: StringParams, eta: float) -> Chain:
    """The axial chain: hook (imposed), bit end 1 - mu/3, pipe mu, element stiffness N*eta^2.

    Parameters
    ----------
    string : StringParams
        The pipe.
    eta : float
        The scaled axial stiffness parameter of (15).

    Returns
    -------
    Chain
        In units of M and M/t*^2; a massless spring (one element, bit mass 1, stiffness
        eta^2) unless the axial pipe is distributed. ``inertia[0]`` is the hook's share, which
        no equation uses (the hook's motion is imposed).
    """
    if not string.axial_distributed:
        return Chain(np.array([0.0, 1.0]), eta * eta)
    n = string.elements
    mu = string.axial_mass_ratio
    m = np.full(n + 1, mu / n)
    m[0] = mu / (2 * n)
    m[-1] = (1.0 - mu / 3.0) + mu / (2 * n)
    return Chain(m, n * (eta * eta))


def max_elements(string: StringParams, rho: float, eta: float, h: float) -> int:
    """The largest N whose chain the explicit RK4 of step h integrates stably.

    RK4 is stable on an undamped oscillator for h*omega <= 2*sqrt(2); the chain's highest
    frequency is below 2*sqrt(k/J_min) (Gershgorin), so N is accepted while
    h*2*sqrt(k/J_min) <= 2.5 in both directions (a margin below 2.83).

    Parameters
    ----------
    string : StringParams
        The pipe (its number of elements is ignored).
    rho, eta : float
        Table inertia and axial stiffness parameter of the scaled set.
    h : float
        The integrator's step.

    Returns
    -------
    int
        The bound, at most :data:`MAX_ELEMENTS`.
    """
    bound = 2.5 / (2.0 * h)  # omega_max allowed
    # torsion: k = N, J_inner = kappa/N: omega ~ 2N/sqrt(kappa)
    n_t = MAX_ELEMENTS if string.kappa == 0.0 else int(bound * math.sqrt(string.kappa))
    n_a = MAX_ELEMENTS
    if string.axial_mass_ratio > 0.0:
        n_a = int(bound * math.sqrt(string.axial_mass_ratio) / eta)
    return max(1, min(MAX_ELEMENTS, n_t, n_a))


__all__ = [
    "LUMPINGS",
    "MAX_ELEMENTS",
    "REFERENCE_KAPPA",
    "Chain",
    "StringParams",
    "axial_chain",
    "max_elements",
    "torsional_chain",
]


# --------------------------------------------------------------------------------------------
# the string of each named rig
# --------------------------------------------------------------------------------------------

# appended below the string's definitions above, which stay as they were

#: The pipe of each named physical rig (:data:`~drillstring.model.params.KNOWN_PHYSICAL`) as
#: the one-element (paper) string, by the rig's name. ``"reference-rig"``: kappa =
#: :data:`REFERENCE_KAPPA` and a massless axial spring (axial mass ratio 0: the paper's K is not
#: the pipe's EA/L, ``docs/reference_rig.md``); ``"pipe-rig"``: the same pipe, whose M and K are
#: its own, so the axial mass ratio is the pipe's mass over M (2.19: the bit end keeps
#: 1 - mu/3 = 0.27 of M, the bottom-hole assembly).
KNOWN_STRINGS: dict[str, StringParams] = {
    "reference-rig": StringParams(kappa=REFERENCE_KAPPA, axial_mass_ratio=0.0),
    "pipe-rig": StringParams(
        kappa=REFERENCE_KAPPA, axial_mass_ratio=REFERENCE_PIPE_MASS / PIPE_RIG.M
    ),
}


def rig_string(name: str, elements: int = 1, lumping: str | None = None) -> StringParams:
    """The pipe of a named rig as a string of ``elements`` elements.

    Parameters
    ----------
    name : str
        A key of :data:`KNOWN_STRINGS` (``"reference-rig"``, ``"pipe-rig"``).
    elements : int
        N, the number of elements (default 1).
    lumping : str, optional
        As :class:`StringParams` (default: ``"paper"`` for one element, ``"lumped"`` otherwise).

    Returns
    -------
    StringParams
        The rig's kappa and axial mass ratio with ``elements`` and ``lumping``.

    Raises
    ------
    ValueError
        ``name`` is not a rig with a known string (the message lists them), or ``elements`` or
        ``lumping`` is invalid (as :class:`StringParams`).
    """
    if not isinstance(name, str) or name not in KNOWN_STRINGS:
        known = ", ".join(sorted(KNOWN_STRINGS))
        raise ValueError(f"no string is known for the rig {name!r} (known: {known})")
    base = KNOWN_STRINGS[name]
    return StringParams(
        elements=elements,
        kappa=base.kappa,
        axial_mass_ratio=base.axial_mass_ratio,
        lumping=lumping,
    )


#: The fields of a physical rig that fix its pipe's string (its speed and feed do not).
_PIPE_FIELDS = ("M", "I1", "I2", "C", "K")


def string_of_rig(rig: object, elements: int) -> StringParams | None:
    """A rig's drill pipe as ``elements`` elements (None for one: the paper's one-mode model).

    The pipe of a known rig (:data:`KNOWN_STRINGS`) when ``rig`` has its masses, inertias and
    stiffnesses, whatever its speed and feed; else (another rig, or no physical rig at all) the
    reference pipe (:class:`StringParams`' defaults).

    Parameters
    ----------
    rig : object
        The physical rig (a :class:`~drillstring.model.params.PhysicalParams`), or anything else
        for a rig without a known pipe.
    elements : int
        N, at least 1.

    Returns
    -------
    StringParams or None
        The string, or None for one element.
    """
    elements = check_int("elements", elements, lower=1)
    if elements == 1:
        return None
    if isinstance(rig, PhysicalParams):
        for name, known in KNOWN_PHYSICAL.items():
            if name in KNOWN_STRINGS and all(
                getattr(known, f) == getattr(rig, f) for f in _PIPE_FIELDS
            ):
                return rig_string(name, elements)
    return StringParams(elements=elements)


__all__ += ["KNOWN_STRINGS", "rig_string", "string_of_rig"]

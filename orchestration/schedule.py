"""The exchange schedule: in which order a master reads outputs, writes inputs and steps units.

Both orders follow from the direct dependencies of the connected outputs on the connected inputs
(FMI 2.0 standard, section 2.2.8, ``ModelStructure/Outputs``):

* :func:`exchange_schedule`: rounds of "read the outputs whose inputs are all fresh, write the
  inputs they feed", until every connected input holds a value computed from consistent inputs.
  A cycle through direct feedthrough is an algebraic loop and is refused with an error naming
  it.
* :func:`gauss_seidel_order`: the default order of the units in a Gauss-Seidel macro step: units
  whose connected outputs have no direct feedthrough from connected inputs first, then the
  others in dependency order.

Variables are ``"unit.variable"`` keys; units are given by their names, in system order.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

__all__ = ["ExchangeRound", "exchange_schedule", "gauss_seidel_order"]


@dataclass(frozen=True)
class ExchangeRound:
    """One round of the exchange schedule.

    Attributes
    ----------
    gets : tuple of (int, tuple of str)
        (unit index, output keys) read in this round, grouped by unit in system order.
    sets : tuple of (int, tuple of str)
        (unit index, input keys) written afterwards from the values just read.
    """

    gets: tuple[tuple[int, tuple[str, ...]], ...]
    sets: tuple[tuple[int, tuple[str, ...]], ...]


def _unit_index(names: Sequence[str], key: str) -> int:
    return names.index(key.split(".", 1)[0])


def _group(names: Sequence[str], keys: Sequence[str]) -> tuple[tuple[int, tuple[str, ...]], ...]:
    by_unit: dict[int, list[str]] = {}
    for k in keys:
        by_unit.setdefault(_unit_index(names, k), []).append(k)
    return tuple((i, tuple(by_unit[i])) for i in sorted(by_unit))


def exchange_schedule(
    names: Sequence[str],
    outputs: Sequence[str],
    deps: Mapping[str, set[str]],
    input_source: Mapping[str, str],
) -> tuple[ExchangeRound, ...]:
    """Rounds of (read the ready outputs, write the inputs they feed) until all are fresh.

    Parameters
    ----------
    names : sequence of str
        Unit names in system order.
    outputs : sequence of str
        Connected outputs, each once.
    deps : mapping
        Connected output -> the connected inputs of its unit it depends on directly.
    input_source : mapping
        Connected input -> its source output.

    Returns
    -------
    tuple of ExchangeRound
        The rounds in execution order.

    Raises
    ------
    ValueError
        For an algebraic loop, naming the outputs that wait for inputs.
    """
    fresh: set[str] = set()
    remaining = list(outputs)
    rounds = []
    while remaining:
        ready = [o for o in remaining if deps[o] <= fresh]
        if not ready:
            loop = ", ".join(f"{o} <- {sorted(deps[o] - fresh)}" for o in remaining)
            raise ValueError(
                "algebraic loop through direct feedthrough (outputs waiting for inputs): "
                f"{loop}. Check the FMUs' ModelStructure/Outputs dependencies."
            )
        remaining = [o for o in remaining if o not in ready]
        ready_set = set(ready)
        targets = [i for i, s in input_source.items() if s in ready_set]
        fresh.update(targets)
        rounds.append(ExchangeRound(gets=_group(names, ready), sets=_group(names, targets)))
    return tuple(rounds)


def gauss_seidel_order(
    names: Sequence[str],
    outputs: Sequence[str],
    deps: Mapping[str, set[str]],
    input_source: Mapping[str, str],
    feedthrough: Sequence[bool],
    given: Sequence[str] | None = None,
) -> tuple[int, ...]:
    """Unit indices in Gauss-Seidel order: ``given`` (checked), or derived from the dependencies.

    Parameters
    ----------
    names, outputs, deps, input_source
        As for :func:`exchange_schedule` (``deps`` must be acyclic: build the schedule first).
    feedthrough : sequence of bool
        Per unit: does a connected output depend directly on a connected input.
    given : sequence of str, optional
        Unit names in the order the user wants.

    Returns
    -------
    tuple of int
        Unit indices.

    Raises
    ------
    ValueError
        If ``given`` does not list every unit exactly once.
    """
    if given is not None:
        given = list(given)
        if sorted(given) != sorted(names):
            raise ValueError(
                f"Gauss-Seidel order {given} must list every unit exactly once: {list(names)}"
            )
        return tuple(names.index(n) for n in given)
    order = [i for i in range(len(names)) if not feedthrough[i]]
    pending = [i for i in range(len(names)) if feedthrough[i]]
    while pending:
        # a feedthrough unit goes once every feedthrough unit feeding its
        # feedthrough inputs is placed (acyclic: the schedule already checked)
        for i in pending:
            needs = {
                _unit_index(names, input_source[inp])
                for o in outputs
                if _unit_index(names, o) == i
                for inp in deps[o]
            }
            if all(j in order or j == i for j in needs):
                order.append(i)
                pending.remove(i)
                break
        else:  # only reachable through a feedthrough cycle across units
            order.extend(pending)
            break
    return tuple(order)

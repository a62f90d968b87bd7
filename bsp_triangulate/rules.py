"""Apex selection rules: which correct candidate becomes the apex of a base edge.

A rule sees the correct candidates of one base edge (sequence positions, in the paper's
candidate order) and picks one. Rules register themselves by name in ``RULES``.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Protocol

import numpy as np


class ApexRule(Protocol):
    """Strategy choosing the apex among the correct candidates of a base edge."""

    name: str
    #: True if the rule needs every correct candidate; False if the first correct one is enough
    #: (the engine may then stop testing at the first correct candidate).
    exhaustive: bool

    def choose(self, correct: np.ndarray, v1: int, v2: int, z: np.ndarray) -> int:
        """Pick one of ``correct`` (positions in candidate order, never empty).

        ``v1``, ``v2`` are the positions of the base edge, ``z`` the elevation of every position.
        """


class FirstRule:
    """The paper's planar rule: the first candidate that forms a correct triangle."""

    name = "first"
    exhaustive = False

    def choose(self, correct: np.ndarray, v1: int, v2: int, z: np.ndarray) -> int:
        return int(correct[0])


class ElevationRule:
    """Paper §4.1: the correct candidate whose z is closest to the mean z of V1 and V2."""

    name = "elevation"
    exhaustive = True

    def choose(self, correct: np.ndarray, v1: int, v2: int, z: np.ndarray) -> int:
        if len(correct) == 1:
            return int(correct[0])
        z1, z2 = float(z[v1]), float(z[v2])
        zc = z[correct]
        approx = np.abs(2.0 * zc - z1 - z2)
        error = 8.0 * 2.0**-53 * (2.0 * np.abs(zc) + abs(z1) + abs(z2)) + 1e-300
        # re-decide near-ties exactly; ties keep the first in candidate order
        close = np.flatnonzero(approx - error <= float((approx + error).min()))
        if len(close) == 1:
            return int(correct[close[0]])
        target = Fraction(z1) + Fraction(z2)
        exact = [abs(2 * Fraction(float(z[correct[i]])) - target) for i in close]
        return int(correct[close[exact.index(min(exact))]])


RULES: dict[str, ApexRule] = {rule.name: rule for rule in (FirstRule(), ElevationRule())}


def get_rule(name: str) -> ApexRule:
    """The registered rule called ``name``; ValueError for an unknown name."""
    try:
        return RULES[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(RULES))
        raise ValueError(f"unknown apex rule {name!r} (known rules: {known})") from None


def register_rule(rule: ApexRule) -> None:
    """Make ``rule`` available under ``rule.name``."""
    RULES[rule.name] = rule

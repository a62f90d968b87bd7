"""Apex selection rules: which correct candidate becomes the apex of a base edge.

A rule sees the correct candidates of one base edge (sequence positions, in the paper's
candidate order) and picks one. Rules register themselves by name in ``RULES``.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Protocol

import numpy as np

from .geometry.predicates import incircle_sos_many


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


class DelaunayRule:
    """The correct candidate that sees the base under the largest angle (docs/algorithm.md,
    "Rule delaunay"): no other correct candidate lies strictly inside its circumcircle with
    the base, so the tree is the constrained Delaunay triangulation of the polygon's vertices.
    Cocircular candidates: ``predicates.cocircular_sign`` decides (a fixed perturbation, so
    the triangulation is unique).

    The rule decides in the working plane, so it has :meth:`choose_in_plane`; the builders
    call that instead of :meth:`choose` (``in_plane`` is True). Under it the bridges are
    constrained Delaunay edges too (``geometry/bridges.py``, ``delaunay=True``). Both
    builders implement it (the lock-step one in ``tree/lockstep.py``, ``_delaunay_apex``).
    """

    name = "delaunay"
    exhaustive = True
    in_plane = True

    def choose(self, correct: np.ndarray, v1: int, v2: int, z: np.ndarray) -> int:
        raise TypeError("rule 'delaunay' decides in the plane: call choose_in_plane")

    def choose_in_plane(
        self, correct: np.ndarray, a: int, b: int, x: np.ndarray, y: np.ndarray
    ) -> int:
        """Pick one of ``correct`` (positions in candidate order, all strictly left of the
        base a -> b): the one with no other strictly inside its circle with a and b, the
        cocircular ones decided by ``predicates.cocircular_sign`` (the first in candidate order
        among occurrences of one point). ``x``, ``y``: coordinates by position."""
        if len(correct) == 1:
            return int(correct[0])
        ax, ay, bx, by = float(x[a]), float(y[a]), float(x[b]), float(y[b])
        cx, cy = x[correct], y[correct]
        # float guess: the circle's centre offset along the base's left normal (smaller is a
        # larger angle), then made exact with the in-circle predicate
        mx, my = 0.5 * (ax + bx), 0.5 * (ay + by)
        nx, ny = ay - by, bx - ax
        ux, uy = cx - mx, cy - my
        half2 = 0.25 * ((bx - ax) * (bx - ax) + (by - ay) * (by - ay))  # no OverflowError
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            offset = (ux * ux + uy * uy - half2) / (ux * nx + uy * ny)
        offset = np.nan_to_num(offset, nan=np.inf, posinf=np.inf, neginf=-np.inf)
        best = int(np.argmin(offset))
        while True:
            # exact, cocircular ties decided by the perturbation (0: the best's own point)
            inside = incircle_sos_many(ax, ay, bx, by, cx[best], cy[best], cx, cy)
            better = np.flatnonzero(inside > 0)
            if len(better) == 0:
                break
            best = int(better[np.argmin(offset[better])])
        # the best's point may occur twice (a bridge end): the first in candidate order
        return int(correct[int(np.flatnonzero(inside == 0)[0])])


RULES: dict[str, ApexRule] = {
    rule.name: rule for rule in (FirstRule(), ElevationRule(), DelaunayRule())
}


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

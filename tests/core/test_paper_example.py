"""The 29-vertex example of the paper (Fig. 1, section 2.2) and its published triangle order.

The paper gives no coordinates, so the polygon below is built to have Fig. 1's structure:
P1 is the hub of a fan, P21-P22 is a bump hidden from P1 and P5-P11 a hooked pocket behind the
mouth P4-P12. The coordinates are integers chosen so that the documented rules alone decide
every step, in particular:
- base P1P23: P22 lies on the line P1P23 (not strictly inside), P20 lies on the side P1P21
  (a vertex on a new side), so P20 is the first correct apex;
- base P1P12: P11 lies on the line P1P12, P10..P6 lie beyond it, P4 lies on the side P1P5,
  so P4 is the first correct apex;
- base P4P9: P9 is a reflex corner and P8, P7, P6 lie beyond the line P4P9, so P5 is first.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import shapely

from bsp_triangulate import triangulate

from .checks import check_triangulation

FIG1 = [
    (-100, 0), (0, 0), (100, 9), (97, 26), (87, 50),  # P0-P4
    (174, 100), (100, 220), (70, 200), (75, 160), (100, 130),  # P5-P9
    (90, 100), (85, 85), (71, 71), (57, 82), (42, 91),  # P10-P14
    (26, 97), (9, 100), (-9, 100), (-26, 97), (-42, 91),  # P15-P19
    (-55, 80), (-77, 112), (-105, 84), (-75, 60), (-87, 50),  # P20-P24
    (-93, 37), (-97, 26), (-98, 17), (-100, 9),  # P25-P28
]  # fmt: skip

# Section 2.2 of the paper, verbatim.
PAPER_ORDER = """
∆P0P1P28 → ∆P1P28P27 → ∆P1P27P26 → ∆P1P26P25 → ∆P1P25P24→∆P1P24P23→∆P1P23P20→∆P1P20P19→
∆P1P19P18→∆P1P18P17→∆P1P17P16→∆P1P16P15→∆P1P15P14→∆P1P14P13→∆P1P13P12 → ∆P1P12P4 →
∆P1P4P3 → ∆P1P3P2 → ∆P12P4P11 → ∆P4P11P10 → ∆P4P10P9 → ∆P4P9P5 → ∆P9P5P8 → ∆P5P8P7 →
∆P5P7P6→∆P23P20P22→∆P20P22P21
"""


def paper_triangles() -> list[tuple[int, int, int]]:
    """(V1, V2, V3) labels of the paper's list."""
    return [
        tuple(int(n) for n in re.findall(r"P(\d+)", t))
        for t in PAPER_ORDER.replace("\n", "").split("→")
    ]


def paper_tree() -> tuple[list[int], list[int]]:
    """Parent and side of each listed triangle: a left child has base V1 V3 of its parent,
    a right child V2 V3 (paper section 2.1.2, step 2)."""
    listed = paper_triangles()
    parent, side = [-1], [0]
    for i, (v1, v2, _) in enumerate(listed[1:], start=1):
        for j in range(i - 1, -1, -1):
            p1, p2, p3 = listed[j]
            if (v1, v2) in ((p1, p3), (p2, p3)):
                parent.append(j)
                side.append(1 if (v1, v2) == (p1, p3) else 2)
                break
    return parent, side


def as_labels(result) -> list[tuple[frozenset, int]]:
    """Each triangle as (base labels, apex label); vertex i of the result is P_i."""
    return [(frozenset(t[:2]), int(t[2])) for t in np.asarray(result.triangles).tolist()]


def expected_labels() -> list[tuple[frozenset, int]]:
    return [(frozenset(t[:2]), t[2]) for t in paper_triangles()]


def test_fig1_polygon_is_a_valid_29_vertex_polygon() -> None:
    assert len(FIG1) == 29
    assert shapely.Polygon(FIG1).is_valid
    assert len(paper_triangles()) == 27


def test_engine_reproduces_the_paper_triangle_order_on_fig1() -> None:
    result = triangulate([FIG1])
    check_triangulation([FIG1], result)
    assert as_labels(result) == expected_labels()
    parent, side = paper_tree()
    assert np.asarray(result.parent).tolist() == parent
    assert np.asarray(result.side).tolist() == side


@pytest.mark.parametrize(
    "transform",
    [
        pytest.param(lambda x, y: (-x, y), id="mirrored-clockwise"),
        pytest.param(lambda x, y: (-y, x), id="rotated-90"),
        pytest.param(lambda x, y: (x + 1e6, y - 2e6), id="translated"),
    ],
)
def test_paper_triangle_order_survives_exact_transforms_of_fig1(transform) -> None:
    """Mirroring (a clockwise ring), rotation and translation change no decision."""
    polygon = [transform(float(x), float(y)) for x, y in FIG1]
    result = triangulate([polygon])
    check_triangulation([polygon], result)
    assert as_labels(result) == expected_labels()

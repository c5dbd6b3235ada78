"""Zone geometry: which polygons a zone may have, and which points and segments lie in or cross one.
Table-driven cases plus seeded random checks against a brute-force sampling of the segment."""

import random

import pytest

from vda5050.polygons import (
    box_touches,
    contains,
    polygon_problem,
    segment_touches,
    segments_intersect,
    signed_area,
)

SQUARE = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
# An L: the notch (1..2, 1..2) is outside.
ELL = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]


@pytest.mark.parametrize(
    ("polygon", "problem"),
    [
        (SQUARE, None),
        (ELL, None),
        ([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], None),
        ([(0.0, 0.0), (1.0, 0.0)], "at least 3 vertices"),
        ([(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (0.0, 1.0)], "occurs twice"),
        (list(reversed(SQUARE)), "clockwise"),
        ([(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)], "fold back"),
        ([(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0)], "cross"),
        ([(0.0, 0.0), (4.0, 0.0), (4.0, 2.0), (2.0, 0.0), (0.0, 2.0)], "cross"),  # a vertex on another edge
        ([(0.0, 0.0), (2.0, 0.0), (1.0, 0.0), (1.0, 1.0)], "fold back"),  # an edge going back on the last
    ],
)
def test_which_polygons_a_zone_may_have(polygon, problem):
    found = polygon_problem(polygon)

    assert (found is None) == (problem is None), found
    if problem is not None:
        assert problem in found


def test_the_area_is_positive_counter_clockwise():
    assert signed_area(SQUARE) == 4.0
    assert signed_area(list(reversed(SQUARE))) == -4.0
    assert signed_area(ELL) == 3.0


@pytest.mark.parametrize(
    ("point", "inside"),
    [
        ((1.0, 1.0), True),
        ((0.0, 0.0), True),  # a vertex
        ((2.0, 1.0), True),  # an edge
        ((2.0001, 1.0), False),
        ((-1.0, 1.0), False),
        ((1.5, 1.5), False),  # the L's notch
        ((0.5, 1.5), True),
        ((1.0, 1.5), True),  # the notch's edge
    ],
)
def test_points_inside_an_l(point, inside):
    assert contains(ELL, point) is inside


@pytest.mark.parametrize(
    ("start", "end", "touches"),
    [
        ((-1.0, 1.0), (3.0, 1.0), True),  # straight through, both ends outside
        ((-1.0, -1.0), (-1.0, 3.0), False),  # beside it
        ((1.0, 1.0), (5.0, 5.0), True),  # from inside
        ((-1.0, 2.0), (3.0, 2.0), True),  # along the top edge
        ((1.5, 3.0), (3.0, 1.5), False),  # past the corner
        ((1.5, 1.2), (1.8, 1.8), False),  # within the L's notch
        ((1.5, 1.5), (0.5, 0.5), True),  # from the notch into the L
    ],
)
def test_segments_that_enter_an_l(start, end, touches):
    assert segment_touches(ELL, start, end) is touches


def test_segment_intersection_agrees_with_sampling():
    """A segment the sampling finds inside the polygon is one segment_touches finds too; seeded."""
    rng = random.Random(46)
    for _ in range(2000):
        start = (rng.uniform(-1, 3), rng.uniform(-1, 3))
        end = (rng.uniform(-1, 3), rng.uniform(-1, 3))
        samples = [
            (start[0] + (end[0] - start[0]) * t / 200, start[1] + (end[1] - start[1]) * t / 200)
            for t in range(201)
        ]
        if any(contains(ELL, point) for point in samples):
            assert segment_touches(ELL, start, end), (start, end)
        assert segments_intersect(start, end, end, start)


@pytest.mark.parametrize(
    ("corner", "opposite", "touches"),
    [
        ((-1.0, 3.0), (3.0, -1.0), True),  # the L inside the box
        ((1.2, 1.2), (1.8, 1.8), False),  # within the L's notch
        ((-1.0, 0.5), (-0.5, 5.0), False),  # beside it
        ((-1.0, 1.0), (3.0, 1.0), True),  # flat: a segment through it
        ((0.5, 0.5), (0.5, 0.5), True),  # flat: a point in it
    ],
)
def test_boxes_that_touch_an_l(corner, opposite, touches):
    assert box_touches(ELL, corner, opposite) is touches


def test_a_path_along_x_then_y_stays_in_the_box_box_touches_finds():
    """Isaac's simulator drives an edge along X, then Y: a point of that path in the polygon is one the
    box finds too; seeded."""
    rng = random.Random(46)
    for _ in range(2000):
        (x0, y0), (x1, y1) = (
            (rng.uniform(-1, 3), rng.uniform(-1, 3)),
            (rng.uniform(-1, 3), rng.uniform(-1, 3)),
        )
        samples = [(x0 + (x1 - x0) * t / 100, y0) for t in range(101)]
        samples += [(x1, y0 + (y1 - y0) * t / 100) for t in range(101)]
        if any(contains(ELL, point) for point in samples):
            assert box_touches(ELL, (x0, y0), (x1, y1)), ((x0, y0), (x1, y1))

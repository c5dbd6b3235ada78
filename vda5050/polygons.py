"""Plane geometry of VDA 5050 3.0 zones: whether a polygon is one a zone may have, and which points and
segments of a route lie in or cross it. Pure; points are (x, y) in metres on one map. The fleet's access
core (`dispatch.zones`) and the simulator's robots (`simulator.zones`) judge routes by the same rules.

A point on a polygon's boundary counts as inside: a robot standing on a zone's edge is in its way.
"""

from __future__ import annotations

from collections.abc import Sequence

Point = tuple[float, float]
Polygon = Sequence[Point]

MIN_VERTICES = 3


def signed_area(polygon: Polygon) -> float:
    """Shoelace area: positive when the vertices go counter-clockwise (as VDA 5050 asks)."""
    total = 0.0
    for (x1, y1), (x2, y2) in _edges(polygon):
        total += x1 * y2 - x2 * y1
    return total / 2.0


def polygon_problem(polygon: Polygon) -> str | None:
    """Why `polygon` cannot outline a zone, or None: at least three vertices, no vertex twice, counter-
    clockwise, enclosing an area, no edge crossing another (a simple polygon)."""
    if len(polygon) < MIN_VERTICES:
        return f"A zone needs at least {MIN_VERTICES} vertices, got {len(polygon)}."
    if len(set(polygon)) != len(polygon):
        return "A vertex occurs twice."
    edges = list(_edges(polygon))
    count = len(edges)
    for i in range(count):
        for j in range(i + 1, count):
            if j == i + 1 or (i == 0 and j == count - 1):
                if _overlap_of_neighbours(edges[i], edges[j]):
                    return f"Edges {i} and {j} fold back on each other."
                continue
            if segments_intersect(*edges[i], *edges[j]):
                return f"Edges {i} and {j} cross: the polygon must not intersect itself."
    area = signed_area(polygon)
    if area == 0.0:
        return "The vertices enclose no area."
    if area < 0.0:
        return "The vertices go clockwise; VDA 5050 lists them counter-clockwise."
    return None


def contains(polygon: Polygon, point: Point) -> bool:
    """Whether `point` lies inside `polygon` or on its boundary (even-odd rule)."""
    x, y = point
    inside = False
    for a, b in _edges(polygon):
        if _on_segment(a, b, point):
            return True
        (x1, y1), (x2, y2) = a, b
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def segment_touches(polygon: Polygon, start: Point, end: Point) -> bool:
    """Whether the straight segment from `start` to `end` enters `polygon` (or touches its boundary)."""
    if contains(polygon, start) or contains(polygon, end):
        return True
    return any(segments_intersect(start, end, a, b) for a, b in _edges(polygon))


def box_touches(polygon: Polygon, corner: Point, opposite: Point) -> bool:
    """Whether the axis-aligned box with opposite corners `corner` and `opposite` (flat: a segment or a
    point) shares a point with `polygon`: whatever path a robot takes between two nodes, straight or
    L-shaped (along X, then Y, as Isaac's reference simulator drives), it stays in that box as long as it
    never drives away from the next node in X or Y."""
    (x0, y0), (x1, y1) = corner, opposite
    low_x, high_x, low_y, high_y = min(x0, x1), max(x0, x1), min(y0, y1), max(y0, y1)
    if any(low_x <= x <= high_x and low_y <= y <= high_y for x, y in polygon):
        return True
    box = [(low_x, low_y), (high_x, low_y), (high_x, high_y), (low_x, high_y)]
    return any(segment_touches(polygon, a, b) for a, b in _edges(box))


def segments_intersect(p1: Point, p2: Point, q1: Point, q2: Point) -> bool:
    """Whether segments p1-p2 and q1-q2 share a point (touching counts)."""
    d1, d2 = _orientation(q1, q2, p1), _orientation(q1, q2, p2)
    d3, d4 = _orientation(p1, p2, q1), _orientation(p1, p2, q2)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return (
        (d1 == 0 and _on_segment(q1, q2, p1))
        or (d2 == 0 and _on_segment(q1, q2, p2))
        or (d3 == 0 and _on_segment(p1, p2, q1))
        or (d4 == 0 and _on_segment(p1, p2, q2))
    )


def _edges(polygon: Polygon) -> list[tuple[Point, Point]]:
    return [(polygon[i], polygon[(i + 1) % len(polygon)]) for i in range(len(polygon))]


def _orientation(a: Point, b: Point, c: Point) -> float:
    """> 0 if a, b, c turn left, < 0 if right, 0 if collinear."""
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _on_segment(a: Point, b: Point, p: Point) -> bool:
    return (
        _orientation(a, b, p) == 0
        and min(a[0], b[0]) <= p[0] <= max(a[0], b[0])
        and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])
    )


def _overlap_of_neighbours(first: tuple[Point, Point], second: tuple[Point, Point]) -> bool:
    """Two edges that share a vertex overlap beyond it when they are collinear and point back."""
    (a, b), (c, d) = first, second
    shared = b if b in (c, d) else a
    one = a if shared == b else b
    other = d if shared == c else c
    if _orientation(shared, one, other) != 0:
        return False
    return (one[0] - shared[0]) * (other[0] - shared[0]) + (one[1] - shared[1]) * (other[1] - shared[1]) > 0

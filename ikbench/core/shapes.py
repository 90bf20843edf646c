"""Path shapes in 3-D: polylines, splines and stroked curves, resampled by arc length.

A :class:`Curve` is a list of pen-down strokes (dense polylines [mm]) joined by straight
pen-up moves. :meth:`Curve.resample` spreads n+1 points evenly by arc length over the whole
path (pen-up moves included, so the arm has goal points while it moves between strokes) and
marks the points that lie strictly inside a pen-up move; metrics skip those.

Control-point files (:func:`read_points_csv`) hold points in mm in the robot's torso frame.
A spline through them is a centripetal Catmull-Rom spline (:func:`catmull_rom`): it passes
through every control point and, unlike the uniform variant, makes no cusps or loops between
unevenly spaced points.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError

#: Consecutive control points closer than this [mm] are merged.
DUPLICATE_TOLERANCE_MM = 1e-9
#: Dense samples per Catmull-Rom span (chord error << 0.01 mm at NICO's scale).
SPLINE_SAMPLES_PER_SPAN = 64
MIN_CONTROL_POINTS = 2
DISTANCE_CHUNK = 64
SPLINE_ALPHA = 0.5  # centripetal


@dataclass(frozen=True)
class Plane:
    """A drawing plane: origin [mm] and orthonormal in-plane axes u (right) and v (up)."""

    origin_mm: np.ndarray
    u: np.ndarray
    v: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        """u x v."""
        return np.cross(self.u, self.v)

    def project(self, points_mm: npt.ArrayLike) -> np.ndarray:
        """In-plane coordinates (N, 2) [mm] of points (N, 3)."""
        rel = np.asarray(points_mm, dtype=float) - self.origin_mm
        return np.stack([rel @ self.u, rel @ self.v], axis=-1)


@dataclass(frozen=True)
class Resampled:
    """n+1 points evenly spaced by arc length along a curve.

    Attributes:
        points_mm: (n+1, 3) points on the path.
        tangents: (n+1, 3) unit direction of the path at each point (of the path segment the
            point lies on; at a vertex, of the segment leaving it).
        pen_down: (n+1,) False for points strictly inside a pen-up move.
    """

    points_mm: np.ndarray
    tangents: np.ndarray
    pen_down: np.ndarray


#: Spacing [mm] of the samples along a curve's strokes that :meth:`Curve.coverage` checks.
COVERAGE_SPACING_MM = 1.0


@dataclass(frozen=True, eq=False)
class Curve:
    """Pen-down strokes, drawn in order, joined by straight pen-up moves.

    Attributes:
        strokes_mm: dense polylines (k_i, 3) [mm], each with k_i >= 2 distinct points.
        plane: the drawing plane when the curve was drawn in one (letters); None otherwise.
    """

    strokes_mm: tuple[np.ndarray, ...]
    plane: Plane | None = None

    def path(self) -> tuple[np.ndarray, np.ndarray]:
        """The whole path as one polyline: vertices (m, 3) and per-segment pen flags (m-1,)."""
        vertices, pen = [self.strokes_mm[0]], [np.ones(len(self.strokes_mm[0]) - 1, bool)]
        for stroke in self.strokes_mm[1:]:
            pen.append(np.zeros(1, bool))  # the pen-up move from the previous stroke's end
            vertices.append(stroke)
            pen.append(np.ones(len(stroke) - 1, bool))
        return np.concatenate(vertices), np.concatenate(pen)

    @property
    def length_mm(self) -> float:
        """Length of the path including pen-up moves [mm]."""
        vertices, _ = self.path()
        return float(np.linalg.norm(np.diff(vertices, axis=0), axis=1).sum())

    def resample(self, steps: int) -> Resampled:
        """n+1 = ``steps`` + 1 points evenly spaced by arc length over the whole path."""
        vertices, pen = self.path()
        segments = np.diff(vertices, axis=0)
        lengths = np.linalg.norm(segments, axis=1)
        keep = lengths > 0  # a pen-up move of length 0 joins strokes that touch
        vertices = np.concatenate([vertices[:1], vertices[1:][keep]])
        segments, lengths, pen = segments[keep], lengths[keep], pen[keep]
        cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
        s = np.linspace(0.0, cumulative[-1], steps + 1)
        index = np.clip(np.searchsorted(cumulative, s, side="right") - 1, 0, len(segments) - 1)
        t = ((s - cumulative[index]) / lengths[index])[:, None]
        points = vertices[index] + t * segments[index]
        points[-1] = vertices[-1]
        tangents = segments[index] / lengths[index][:, None]
        inside = (t[:, 0] > 0) & (t[:, 0] < 1)
        pen_down = pen[index] | ~inside
        return Resampled(points, tangents, pen_down)

    def distances_mm(self, points_mm: npt.ArrayLike) -> np.ndarray:
        """Distance [mm] of each point (N, 3) from the nearest pen-down stroke."""
        return distances_to_polylines_mm(points_mm, self.strokes_mm)

    def coverage(self, drawn_mm: Iterable[npt.ArrayLike], within_mm: float,
                 spacing_mm: float = COVERAGE_SPACING_MM) -> float:
        """Share [0, 1] of the pen-down strokes' length within ``within_mm`` [mm] of the
        drawn path: ``drawn_mm``, polylines (k_i, 3) [mm] through the fingertip's pen-down
        points (one per run of consecutive pen-down points). The strokes are sampled every
        ``spacing_mm`` [mm]; a path that stops early leaves the rest uncovered."""
        drawn = [np.asarray(line, dtype=float).reshape(-1, 3) for line in drawn_mm]
        drawn = [line if len(line) > 1 else np.concatenate([line, line])
                 for line in drawn if len(line)]
        if not drawn:
            return 0.0
        samples = [_samples(stroke, spacing_mm) for stroke in self.strokes_mm]
        distances = distances_to_polylines_mm(np.concatenate(samples), drawn)
        return float(np.mean(distances <= within_mm))

    def drawing_plane(self) -> Plane:
        """The curve's plane, or the best-fit plane of its strokes (principal axes)."""
        return self.plane or best_fit_plane(np.concatenate(self.strokes_mm))


def _samples(polyline_mm: np.ndarray, spacing_mm: float) -> np.ndarray:
    """Points evenly spaced by arc length along a polyline (k, 3) [mm], at most
    ``spacing_mm`` [mm] apart, both ends included."""
    lengths = np.linalg.norm(np.diff(polyline_mm, axis=0), axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.linspace(0.0, cumulative[-1], max(2, int(np.ceil(cumulative[-1] / spacing_mm)) + 1))
    return np.stack([np.interp(s, cumulative, polyline_mm[:, k]) for k in range(3)], axis=1)


def distances_to_polylines_mm(points_mm: npt.ArrayLike,
                              polylines: Iterable[np.ndarray]) -> np.ndarray:
    """Distance [mm] of each point (N, 3) from the nearest segment of any polyline (k_i, 3)."""
    points = np.asarray(points_mm, dtype=float).reshape(-1, 3)
    starts = np.concatenate([p[:-1] for p in polylines])        # (M, 3)
    axis = np.concatenate([p[1:] for p in polylines]) - starts
    length2 = np.maximum(np.sum(axis**2, axis=1), 1e-300)
    out = np.empty(len(points))
    for k in range(0, len(points), DISTANCE_CHUNK):             # bounds memory to (chunk, M, 3)
        chunk = points[k:k + DISTANCE_CHUNK, None, :]
        t = np.clip(np.sum((chunk - starts) * axis, axis=-1) / length2, 0.0, 1.0)
        nearest = starts + t[..., None] * axis
        out[k:k + DISTANCE_CHUNK] = np.min(np.linalg.norm(chunk - nearest, axis=-1), axis=1)
    return out


def best_fit_plane(points_mm: npt.ArrayLike) -> Plane:
    """Plane through the centroid spanned by the two principal axes of the points.

    Signs are fixed so the result is deterministic: v has a non-negative z component (up
    when the plane is not horizontal) and u = v x n with n pointing towards -x when possible.
    """
    points = np.asarray(points_mm, dtype=float)
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=True)
    normal = vt[2]
    if normal[0] > 0 or (normal[0] == 0 and normal[2] < 0):
        normal = -normal
    up = np.array([0.0, 0.0, 1.0]) - normal[2] * normal
    if np.linalg.norm(up) < 1e-9:  # horizontal plane: v along +y instead
        up = np.array([0.0, 1.0, 0.0]) - normal[1] * normal
    v = up / np.linalg.norm(up)
    return Plane(centre, np.cross(v, normal), v)


# ----- control-point files -------------------------------------------------------------------
def read_points_csv(path: str | Path) -> np.ndarray:
    """Read control points (k, 3) [mm] from a CSV file.

    Format: one point per line, ``x,y,z`` in mm in the torso frame; an optional first line
    of column names (e.g. ``x_mm,y_mm,z_mm``; at most one such line, before any point); blank
    lines and lines starting with ``#`` are ignored. Consecutive duplicate points are merged.

    Raises:
        InputError: unreadable file, wrong number of columns, a non-numeric or non-finite
            value (a second header line included), or fewer than 2 distinct points; the
            message names the file and line.
    """
    where = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read shape file {where!r}: {exc}") from None
    rows, seen_line = [], False
    for number, fields in enumerate(csv.reader(text.splitlines()), start=1):
        if not fields or not "".join(fields).strip() or fields[0].lstrip().startswith("#"):
            continue
        first, seen_line = not seen_line, True
        if len(fields) != 3:
            raise InputError(f"{where}, line {number}: expected 3 values x,y,z [mm], "
                             f"got {len(fields)}: {','.join(fields)!r}")
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if first and not any(_is_number(f) for f in fields):
                continue  # the one header line allowed
            bad = next(f for f in fields if not _is_number(f))
            raise InputError(f"{where}, line {number}: {bad.strip()!r} is not a number "
                             "(x,y,z in mm; only the first line may be a header of column "
                             "names)") from None
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{where}, line {number}: {','.join(fields)!r} is not finite")
        rows.append(values)
    points = dedupe(np.array(rows, dtype=float).reshape(-1, 3))
    if len(points) < MIN_CONTROL_POINTS:
        raise InputError(f"{where}: {len(points)} distinct point(s); a shape needs at least "
                         f"{MIN_CONTROL_POINTS}")
    return points


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def dedupe(points: npt.ArrayLike) -> np.ndarray:
    """Drop points closer than :data:`DUPLICATE_TOLERANCE_MM` to their predecessor."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        return points
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([points[:1], points[1:][gaps > DUPLICATE_TOLERANCE_MM]])


# ----- splines -------------------------------------------------------------------------------
def catmull_rom(points: npt.ArrayLike, samples_per_span: int = SPLINE_SAMPLES_PER_SPAN,
                alpha: float = SPLINE_ALPHA) -> np.ndarray:
    """Dense Catmull-Rom spline (m, 3) through control points (k, 3), k >= 2.

    Non-uniform (knot intervals |P_{j+1} - P_j|^alpha; alpha 0.5 = centripetal) in the
    Barry-Goldman form. The end spans use mirrored phantom points 2 P_0 - P_1 and
    2 P_{k-1} - P_{k-2}, so the curve starts and ends heading along its first/last chord.
    """
    p = dedupe(points)
    extended = np.concatenate([[2 * p[0] - p[1]], p, [2 * p[-1] - p[-2]]])
    dense = [p[:1]]
    u = np.linspace(0.0, 1.0, samples_per_span + 1)[1:, None]
    for j in range(len(p) - 1):
        dense.append(_catmull_rom_span(extended[j:j + 4], u, alpha))
    return np.concatenate(dense)


def _catmull_rom_span(p, u, alpha):
    """Points of the span from p[1] to p[2] at fractions u (s, 1) of its knot interval."""
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1)
                                             ** alpha)])
    t0, t1, t2, t3 = knots
    t = t1 + u * (t2 - t1)

    def lerp(a, b, ta, tb):
        return ((tb - t) * a + (t - ta) * b) / (tb - ta)

    a1, a2, a3 = lerp(p[0], p[1], t0, t1), lerp(p[1], p[2], t1, t2), lerp(p[2], p[3], t2, t3)
    b1, b2 = lerp(a1, a2, t0, t2), lerp(a2, a3, t1, t3)
    return lerp(b1, b2, t1, t2)

"""Uppercase letters A-Z as strokes in a unit box, for drawing in the air.

Each letter is a path of straight lines and elliptical arcs in letter coordinates (u to the
right as a viewer facing the robot reads it, v up), cap height 1 (v from 0 to 1), width 0.4
to 0.8. Every letter but X is one continuous stroke (retracing a bar where needed, as a
hand does in the air); X lifts the pen once, and the pen-up move is marked so that metrics
skip it.

:func:`letter_curve` scales a letter to a height in mm and places its box centre at a point
of a drawing plane; by default the frontal plane of the torso frame, u = -y (the robot's
left is the viewer's right) and v = +z, viewed along the plane normal (-1, 0, 0).
"""

from __future__ import annotations

import math
import string

import numpy as np
import numpy.typing as npt

from ikbench.core.errors import InputError
from ikbench.core.shapes import Curve, Plane

#: The paper's letter experiment: start pose [motor deg], letter height [mm], iterations.
PAPER_START_POSE_DEG = (0.0, 45.0, 0.0, 90.0, 180.0, 180.0, -145.0)
DEFAULT_SIZE_MM = 300.0
PAPER_ITERATIONS = 2000
#: Segments n per letter (the paper's lines use 50; a letter is 2-4 times longer).
DEFAULT_STEPS = 100
#: The frontal drawing plane: in-plane axes u (viewer's right), v (up); normal u x v.
FRONTAL_U = np.array([0.0, -1.0, 0.0])
FRONTAL_V = np.array([0.0, 0.0, 1.0])
#: Goal pointing direction for letters: the drawing plane's normal, away from the robot.
LETTER_DIRECTION = np.cross(FRONTAL_U, FRONTAL_V)  # (-1, 0, 0)
#: Loss weights of the paper's letter setting: points, pointing, smoothness; no start/end
#: pose or point terms.
LETTER_WEIGHTS = {"L0": 1.0, "L1": 50.0, "L2": 0.0, "L3": 0.0, "L4": 0.0, "L5": 0.0,
                  "L6": 1.0}
#: Largest angle [deg] between two samples of an arc.
ARC_STEP_DEG = 1.0


def _ellipse(cu, cv, ru, rv, deg):
    a = math.radians(deg)
    return (cu + ru * math.cos(a), cv + rv * math.sin(a))


# Path operations: ("M", u, v) starts a stroke (a pen-up move when one is in progress);
# ("L", u, v) a line to (u, v); ("A", cu, cv, ru, rv, from_deg, to_deg) an elliptical arc
# about (cu, cv), angles counter-clockwise from +u, that starts at the current point (or
# starts the stroke).
LETTERS: dict[str, list[tuple]] = {
    "A": [("M", 0, 0), ("L", 0.3, 1), ("L", 0.6, 0), ("L", 0.495, 0.35), ("L", 0.105, 0.35)],
    "B": [("M", 0, 0), ("L", 0, 1), ("L", 0.3, 1), ("A", 0.3, 0.775, 0.225, 0.225, 90, -90),
          ("L", 0, 0.55), ("L", 0.33, 0.55), ("A", 0.33, 0.275, 0.275, 0.275, 90, -90),
          ("L", 0, 0)],
    "C": [("A", 0.3, 0.5, 0.3, 0.5, 45, 315)],
    "D": [("M", 0, 0), ("L", 0, 1), ("L", 0.15, 1), ("A", 0.15, 0.5, 0.45, 0.5, 90, -90),
          ("L", 0, 0)],
    "E": [("M", 0.55, 1), ("L", 0, 1), ("L", 0, 0.5), ("L", 0.45, 0.5), ("L", 0, 0.5),
          ("L", 0, 0), ("L", 0.55, 0)],
    "F": [("M", 0.55, 1), ("L", 0, 1), ("L", 0, 0.5), ("L", 0.45, 0.5), ("L", 0, 0.5),
          ("L", 0, 0)],
    "G": [("A", 0.3, 0.5, 0.3, 0.5, 45, 360), ("L", 0.35, 0.5)],
    "H": [("M", 0, 1), ("L", 0, 0), ("L", 0, 0.5), ("L", 0.6, 0.5), ("L", 0.6, 1),
          ("L", 0.6, 0)],
    "I": [("M", 0, 1), ("L", 0.4, 1), ("L", 0.2, 1), ("L", 0.2, 0), ("L", 0, 0), ("L", 0.4, 0)],
    "J": [("M", 0.5, 1), ("L", 0.5, 0.25), ("A", 0.25, 0.25, 0.25, 0.25, 0, -180)],
    "K": [("M", 0, 1), ("L", 0, 0), ("L", 0, 0.4), ("L", 0.6, 1), ("L", 0.2, 0.6),
          ("L", 0.6, 0)],
    "L": [("M", 0, 1), ("L", 0, 0), ("L", 0.5, 0)],
    "M": [("M", 0, 0), ("L", 0, 1), ("L", 0.35, 0.4), ("L", 0.7, 1), ("L", 0.7, 0)],
    "N": [("M", 0, 0), ("L", 0, 1), ("L", 0.6, 0), ("L", 0.6, 1)],
    "O": [("A", 0.3, 0.5, 0.3, 0.5, 90, 450)],
    "P": [("M", 0, 0), ("L", 0, 1), ("L", 0.3, 1), ("A", 0.3, 0.75, 0.25, 0.25, 90, -90),
          ("L", 0, 0.5)],
    "Q": [("M", 0.38, 0.28), ("L", *_ellipse(0.3, 0.5, 0.3, 0.5, -45)),
          ("A", 0.3, 0.5, 0.3, 0.5, -45, 315), ("L", 0.66, 0)],
    "R": [("M", 0, 0), ("L", 0, 1), ("L", 0.3, 1), ("A", 0.3, 0.75, 0.25, 0.25, 90, -90),
          ("L", 0, 0.5), ("L", 0.3, 0.5), ("L", 0.6, 0)],
    "S": [("A", 0.3, 0.75, 0.3, 0.25, 20, 270), ("A", 0.3, 0.25, 0.3, 0.25, 90, -160)],
    "T": [("M", 0, 1), ("L", 0.6, 1), ("L", 0.3, 1), ("L", 0.3, 0)],
    "U": [("M", 0, 1), ("L", 0, 0.3), ("A", 0.3, 0.3, 0.3, 0.3, 180, 360), ("L", 0.6, 1)],
    "V": [("M", 0, 1), ("L", 0.3, 0), ("L", 0.6, 1)],
    "W": [("M", 0, 1), ("L", 0.2, 0), ("L", 0.4, 0.7), ("L", 0.6, 0), ("L", 0.8, 1)],
    "X": [("M", 0, 1), ("L", 0.6, 0), ("M", 0, 0), ("L", 0.6, 1)],
    "Y": [("M", 0, 1), ("L", 0.3, 0.5), ("L", 0.6, 1), ("L", 0.3, 0.5), ("L", 0.3, 0)],
    "Z": [("M", 0, 1), ("L", 0.6, 1), ("L", 0, 0), ("L", 0.6, 0)],
}
AVAILABLE = "".join(LETTERS)
#: Tolerance (letter units) for an arc to start at the current point.
_JOIN_TOLERANCE = 1e-9


def parse_letters(text: str) -> list[str]:
    """``"P,a,B"`` -> ``["P", "A", "B"]``; anything but single letters A-Z raises InputError."""
    items = [item.strip() for item in str(text).split(",")]
    for item in items:
        if len(item) != 1 or item.upper() not in LETTERS:
            hint = (f"; separate letters with commas, e.g. {','.join(item)}"
                    if len(item) > 1 and all(c in string.ascii_letters for c in item) else "")
            raise InputError(f"letter {item!r} is not one of A-Z{hint}")
    return [item.upper() for item in items]


def letter_strokes(letter: str) -> list[np.ndarray]:
    """The pen-down strokes (k_i, 2) of a letter in letter coordinates (u, v)."""
    if letter not in LETTERS:
        raise InputError(f"letter {letter!r} is not one of {AVAILABLE}")
    strokes: list[np.ndarray] = []
    current: list[tuple[float, float]] = []
    for op, *args in LETTERS[letter]:
        if op == "M":
            if len(current) > 1:
                strokes.append(np.array(current))
            current = [tuple(args)]
        elif op == "L":
            current.append(tuple(args))
        else:
            arc = _arc_points(*args)
            if current and math.dist(current[-1], arc[0]) > _JOIN_TOLERANCE:
                raise ValueError(f"letter {letter}: arc {args} does not start at {current[-1]}")
            current.extend(arc[1:] if current else arc)
    strokes.append(np.array(current))
    return strokes


def _arc_points(cu, cv, ru, rv, from_deg, to_deg) -> list[tuple[float, float]]:
    count = max(2, math.ceil(abs(to_deg - from_deg) / ARC_STEP_DEG) + 1)
    return [_ellipse(cu, cv, ru, rv, a) for a in np.linspace(from_deg, to_deg, count)]


def letter_box(letter: str) -> tuple[float, float]:
    """(min u, max u) of a letter, in letter units (its height is 1)."""
    u = np.concatenate([s[:, 0] for s in letter_strokes(letter)])
    return float(u.min()), float(u.max())


def letter_curve(letter: str, size_mm: float, centre_mm: npt.ArrayLike,
                 u_axis: npt.ArrayLike = FRONTAL_U, v_axis: npt.ArrayLike = FRONTAL_V) -> Curve:
    """A letter scaled to ``size_mm`` high with its box centred at ``centre_mm``.

    Args:
        letter: one of A-Z.
        size_mm: cap height [mm].
        centre_mm: (3,) where the centre of the letter's box goes [mm].
        u_axis, v_axis: orthonormal in-plane axes (right and up as the viewer reads it).

    Returns:
        A :class:`Curve` whose plane has its origin at ``centre_mm``.
    """
    if not (size_mm > 0 and math.isfinite(size_mm)):
        raise InputError(f"size_mm: {size_mm!r} must be a positive number of mm")
    u_axis, v_axis = np.asarray(u_axis, float), np.asarray(v_axis, float)
    centre = np.asarray(centre_mm, dtype=float)
    u_lo, u_hi = letter_box(letter)
    offset = np.array([(u_lo + u_hi) / 2.0, 0.5])
    strokes = tuple(
        centre + size_mm * ((s[:, :1] - offset[0]) * u_axis + (s[:, 1:] - offset[1]) * v_axis)
        for s in letter_strokes(letter)
    )
    return Curve(strokes, Plane(centre, u_axis, v_axis))

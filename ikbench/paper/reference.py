"""The authors' published trajectories, shipped with ikbench in ``data/reference/``.

Copied from the paper authors' public repository andylucny/nico2 and converted to CSV (the
folder's ``README.md`` says from where, and what the figures measured from them are):
``adam`` is the paper's method (Table 1), ``sequential-ikpy`` its ikpy baseline (Table 2,
solved on another NICO URDF). Poses are in motor degrees, 51 per trajectory.

Example::

    from ikbench.paper.reference import authors_trajectory
    poses_deg = authors_trajectory("adam", 3)   # (51, 7) [motor deg]
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from ikbench.core.errors import InputError

#: The folder of the shipped reference data (README.md, authors-trajectories/).
REFERENCE_DIR = Path(str(resources.files("ikbench.paper").joinpath("data", "reference")))
#: kind -> file name pattern in ``authors-trajectories/``.
KINDS = {"adam": "adam_trajectory_{k}.csv",
         "sequential-ikpy": "sequential_ikpy_trajectory_{k}.csv"}
#: The paper's trajectory ids.
TRAJECTORIES = tuple(str(k) for k in range(1, 8))
#: Joint columns of the files, in the paper's order (motor degrees).
JOINTS = ("r_shoulder_z", "r_shoulder_y", "r_arm_x", "r_elbow_y", "r_wrist_z", "r_wrist_x",
          "r_indexfinger_x")


def authors_trajectory_path(kind: str = "adam", k: int | str = 1) -> Path:
    """The CSV of the authors' trajectory ``k`` (1..7) of ``kind`` (``adam`` or
    ``sequential-ikpy``); InputError naming the allowed values otherwise."""
    if kind not in KINDS:
        raise InputError(f"reference kind {kind!r} is not one of {', '.join(KINDS)}")
    if str(k) not in TRAJECTORIES:
        raise InputError(f"reference trajectory {k!r} is not one of {', '.join(TRAJECTORIES)}")
    return REFERENCE_DIR / "authors-trajectories" / KINDS[kind].format(k=k)


def authors_trajectory(kind: str = "adam", k: int | str = 1) -> np.ndarray:
    """Poses (51, 7) [motor deg] of the authors' trajectory ``k`` of ``kind``."""
    import pandas as pd

    frame = pd.read_csv(authors_trajectory_path(kind, k))
    return frame[list(JOINTS)].to_numpy(dtype=float)

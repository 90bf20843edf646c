"""Robots by name from installed robot description packages (``--robot example-robot-data:ur5``).

A robot description package on PyPI ships URDFs whose meshes are ``package://`` URIs
(example-robot-data 6: UR3/5/10, Panda, xArm, Kinova, Talos, Tiago, ... under
``site-packages/cmeel.prefix/share/example-robot-data/robots/``). ``PACKAGE:NAME`` names one:

- NAME in :data:`ARMS` (the common arms): the URDF, base link and end frame come from that
  table (``--end-frame`` may still replace the end frame);
- any other URDF of the package by its file stem (``example-robot-data:so101``): the chain runs
  from the URDF's root to ``--end-frame LINK``, which is then required.

A robot config's ``urdf`` may be such a name too (``urdf = "example-robot-data:romeo"``, as
``ikbench robot init`` writes for a package robot): :func:`package_urdf` finds its file in the
package installed where the config is loaded, so the config holds no path into a venv.

:func:`resolve_package_uri` turns a ``package://pkg/path`` URI into a file of an installed
package (the viewer's meshes). The package is optional: ``pip install 'ikbench[robots]'``;
without it, such names are refused with one line naming the extra.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from ikbench.core.errors import InputError
from ikbench.core.urdf_model import load_urdf_model

#: Distribution -> the folder (inside the distribution's files) that holds its robots.
PACKAGES = {"example-robot-data": "cmeel.prefix/share/example-robot-data/robots"}
#: Folders that ``package://NAME/...`` URIs are resolved against (inside the distributions).
SHARE = {"example-robot-data": "cmeel.prefix/share"}
EXTRA = "pip install 'ikbench[robots]'"


@dataclass(frozen=True)
class Arm:
    """A common arm of a description package: its URDF (relative to the package's robots
    folder), the chain's base link and end frame, and a line describing it."""

    urdf: str
    base_link: str
    end_frame: str
    description: str


#: The common arms, name -> :class:`Arm` (example-robot-data 6.0.0's link names).
ARMS: dict[str, dict[str, Arm]] = {"example-robot-data": {
    "ur3": Arm("ur_description/urdf/ur3_robot.urdf", "base_link", "tool0",
               "Universal Robots UR3, 6 joints, base_link -> tool0"),
    "ur5": Arm("ur_description/urdf/ur5_robot.urdf", "base_link", "tool0",
               "Universal Robots UR5, 6 joints, base_link -> tool0"),
    "ur10": Arm("ur_description/urdf/ur10_robot.urdf", "base_link", "tool0",
                "Universal Robots UR10, 6 joints, base_link -> tool0"),
    "panda": Arm("panda_description/urdf/panda.urdf", "panda_link0", "panda_link8",
                 "Franka Emika Panda, 7 joints, panda_link0 -> panda_link8 (MoveIt's "
                 "panda_arm group, as in PickNik's ik_benchmarking)"),
    "xarm7": Arm("xarm_description/urdf/xarm7.urdf", "link_base", "link_eef",
                 "UFACTORY xArm7, 7 joints, link_base -> link_eef"),
    "kinova": Arm("kinova_description/robots/kinova.urdf", "j2s6s200_link_base",
                  "j2s6s200_end_effector",
                  "Kinova Jaco2 j2s6s200, 6 joints (3 continuous), base -> end effector"),
    "talos_left_arm": Arm("talos_data/robots/talos_reduced.urdf", "torso_2_link",
                          "gripper_left_base_link",
                          "PAL Talos left arm, 7 joints, torso_2_link -> gripper base"),
    "tiago_arm": Arm("tiago_description/robots/tiago.urdf", "torso_lift_link",
                     "arm_tool_link", "PAL Tiago arm, 7 joints, torso_lift_link -> "
                     "arm_tool_link (torso lift locked at 0)"),
    "z1": Arm("z1_description/urdf/z1.urdf", "link00", "gripperStator",
              "Unitree Z1, 6 joints, link00 -> gripperStator (the gripper's fixed jaw; "
              "its moving jaw left out)"),
}}


def is_package_name(name: str) -> bool:
    """True for ``PACKAGE:NAME`` with a known PACKAGE (not a Windows drive or a path)."""
    package, sep, rest = name.partition(":")
    return bool(sep) and package in PACKAGES and bool(rest) and "/" not in rest


def _distribution_root(package: str) -> Path | None:
    """The folder the distribution's files are relative to, or None when not installed."""
    try:
        dist = metadata.distribution(package)
    except metadata.PackageNotFoundError:
        return None
    return Path(str(dist.locate_file("")))


def robots_folder(package: str) -> Path | None:
    """The installed package's robots folder, or None when the package is not installed."""
    root = _distribution_root(package)
    folder = None if root is None else root / PACKAGES[package]
    return folder if folder is not None and folder.is_dir() else None


def package_urdfs(package: str) -> dict[str, Path]:
    """stem -> URDF of every URDF in the installed package (empty when not installed)."""
    folder = robots_folder(package)
    if folder is None:
        return {}
    return {p.stem: p for p in sorted(folder.rglob("*.urdf"))}


def resolve(name: str, end_frame: str | None) -> tuple[Path, str | None, str, str]:
    """(URDF path, base link or None: the URDF's root, end frame, description) of
    ``PACKAGE:NAME``.

    Raises:
        InputError: the package is not installed, NAME is neither a common arm nor a URDF of
            the package, or a URDF outside the table comes without ``--end-frame``.
    """
    package, _, robot = name.partition(":")
    path = package_urdf(name)  # refuses a package not installed and an unknown NAME
    arm = ARMS.get(package, {}).get(robot)
    if arm is not None:
        return path, arm.base_link, end_frame or arm.end_frame, f"{arm.description} ({package})"
    if not end_frame:
        urdf = load_urdf_model(path)  # a broken file is refused before the end frame
        raise InputError(f"robot: {name}: not in ikbench's table of common arms; give its "
                         "end frame, a link (--end-frame LINK; the chain runs from the URDF's "
                         f"root to it); {urdf.candidates_text()}")
    return path, None, end_frame, f"{path.name} from {package}"


def package_urdf(name: str) -> Path:
    """The URDF of ``PACKAGE:NAME`` (a common arm's, or the package's URDF of that stem): what
    a robot config's ``urdf = "PACKAGE:NAME"`` refers to.

    Raises:
        InputError: the package is not installed, or NAME is neither a common arm nor a URDF
            of the package.
    """
    package, _, robot = name.partition(":")
    folder = robots_folder(package)
    if folder is None:
        raise InputError(f"robot: {name}: the package {package} is not installed ({EXTRA})")
    arm = ARMS.get(package, {}).get(robot)
    if arm is not None:
        return folder / arm.urdf
    urdfs = package_urdfs(package)
    if robot not in urdfs:
        raise InputError(f"robot: {name}: {robot!r} is neither a common arm of {package} "
                         f"({', '.join(ARMS.get(package, {}))}) nor one of its URDFs "
                         f"({', '.join(urdfs)})")
    return urdfs[robot]


def resolve_package_uri(uri: str) -> Path | None:
    """The file a ``package://pkg/path`` URI names in an installed description package, or
    None when no installed package holds it."""
    if not uri.startswith("package://"):
        return None
    rest = uri[len("package://"):]
    for package, share in SHARE.items():
        root = _distribution_root(package)
        if root is not None and (root / share / rest).is_file():
            return root / share / rest
    return None


def listing() -> list[dict]:
    """One entry per robot of every installed description package: name (``PACKAGE:NAME``),
    URDF, and the table's base link and end frame (None for URDFs that need --end-frame; those
    give ``end_frame_candidates``, or ``refused``: why the URDF cannot be used)."""
    out: list[dict] = []
    for package in PACKAGES:
        folder = robots_folder(package)
        if folder is None:
            continue
        arms = ARMS.get(package, {})
        for robot, arm in arms.items():
            out.append({"name": f"{package}:{robot}", "urdf": str(folder / arm.urdf),
                        "base_link": arm.base_link, "end_frame": arm.end_frame,
                        "description": arm.description})
        for stem, path in package_urdfs(package).items():
            if stem not in arms:
                out.append({"name": f"{package}:{stem}", "urdf": str(path), "base_link": None,
                            "end_frame": None, "description": "needs --end-frame LINK",
                            **_candidates(path)})
    return out


def _candidates(urdf: Path) -> dict:
    """``{"end_frame_candidates": [...]}`` of a URDF (leaf links first, then tool-like
    names), or ``{"refused": "one line"}`` when the URDF cannot be used."""
    try:
        return {"end_frame_candidates": list(load_urdf_model(urdf).end_frame_candidates())}
    except InputError as exc:
        return {"refused": " ".join(str(exc).split())}

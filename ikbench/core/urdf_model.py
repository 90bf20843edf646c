"""A URDF read once, through yourdfpy: links, joints, limits, velocities, collision elements.

:func:`load_urdf_model` parses a URDF file with yourdfpy (no scene graph, no meshes) into a
:class:`UrdfModel`, cached per file and content, so every consumer reads the same model: the
robot's chain and limits (:mod:`ikbench.core.robot`), the velocity limits of the contract and
of ``--timing topp``, the root link Drake welds, the path ikpy follows. Units are the URDF's:
metres, radians, m/s and rad/s.

The URDF text handed to a kinematics library (Pinocchio, pytorch-kinematics, ikpy, TRAC-IK,
Drake, MuJoCo, PyRoki) is written from the model by :meth:`UrdfModel.to_xml` (yourdfpy's
writer), with the edits a consumer asks for: visual or collision elements left out, joints
held fixed at a value, continuous joints as wide revolute ones, unit axes. yourdfpy keeps an
origin as a 4x4 matrix and writes it back as ``xyz`` / ``rpy`` at full precision (``rpy``
through ``trimesh.transformations.euler_from_matrix``; a -0.0 it gives is written 0.0, as the
file had it: PyRoki's rotations follow the sign of a zero): the shipped URDFs come back with
every number unchanged, others as the same placements (to ~1e-16; an angle may come back wrapped,
e.g. ``-3.1416`` for ``3.1416``). yourdfpy writes no ``<mimic>``, ``<calibration>``,
``<safety_controller>``, ``<transmission>`` or ``<gazebo>`` elements: none of them changes the
kinematics the libraries build here.

A file is checked once, when it is parsed, before any library sees it (:func:`load_urdf_model`):
unique link and joint names, joints that name defined links, known joint types, a ``<limit>``
(with ``effort`` and ``velocity``, finite numbers, ``lower <= upper``) on every revolute and
prismatic joint, a finite non-zero ``<axis>`` on every movable joint, finite origins, and a
tree (one root link, one parent joint per link, no loop). A file that breaks one of these is
refused with one line naming the joint or link and what is allowed (urdfdom, Pinocchio's
reader, would print its own error and raise, or build NaNs from a zero axis); what yourdfpy
and trimesh warn while parsing such a file is folded into that line, not printed before it.
Before it is parsed, a file larger than :data:`MAX_URDF_BYTES` or with more than
:data:`MAX_LINKS` ``<link>`` elements is refused (one line, in well under a second: parsing
a file of 200,000 links takes yourdfpy minutes and gigabytes).

A parsed model is also kept on disk (:func:`cache_folder`: ``$XDG_CACHE_HOME/ikbench/urdf``,
``~/.cache/ikbench/urdf`` by default; ``IKBENCH_URDF_CACHE=0`` turns it off), keyed by the
file's path and bytes and by this module's own source, so a new process reads a robot without
importing yourdfpy and trimesh (most of a first call's wait, issue 63). Only files that
parsed without a warning are kept; yourdfpy's tree, which only the URDF writer needs
(:meth:`UrdfModel.to_xml`, :meth:`UrdfModel.to_yourdfpy`), is parsed again from the same
bytes when first asked for.

The joints of a robot's chain are checked further when the robot is built
(:func:`ikbench.core.robot.chain_joints`, with :data:`MAX_LIMIT_RAD` and
:data:`MAX_LIMIT_M`): a file may hold a gripper's mimic joint or a wheel without a speed
limit as long as no chain runs through it.
:meth:`UrdfModel.end_frame_candidates` lists the links an end frame may be (the errors that
ask for one name them).
"""

from __future__ import annotations

import copy
import hashlib
import io
import logging
import math
import os
import pickle
import re
import warnings
from collections import Counter, OrderedDict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError

if TYPE_CHECKING:
    from collections.abc import Mapping

    import yourdfpy

#: URDF joint types that move (fixed joints are constant transforms).
MOVABLE_TYPES = ("revolute", "continuous", "prismatic")
#: Every joint type of the URDF specification.
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: Joint types that must give a ``<limit>`` (urdfdom refuses them without).
LIMITED_TYPES = ("revolute", "prismatic")
#: Joint types whose ``<axis>`` is used (a fixed or floating joint's is ignored).
AXIS_TYPES = ("revolute", "continuous", "prismatic", "planar")
#: Words of a link name that suggest a tool or end-effector frame (end frame candidates).
TOOL_WORDS = ("tool", "tcp", "ee", "end", "gripper", "hand", "flange", "finger", "tip")
#: How many parsed files :func:`load_urdf_model` keeps.
CACHE_SIZE = 32
#: The largest URDF file read [bytes] (the largest of example-robot-data 6 is 0.3 MB).
MAX_URDF_BYTES = 20_000_000
#: The most ``<link>`` elements a URDF read may hold (example-robot-data 6: at most 130).
MAX_LINKS = 5000
#: The largest |lower|, |upper| of a revolute chain joint [rad] (a joint without limits is
#: ``type="continuous"``).
MAX_LIMIT_RAD = 1e4
#: The largest |lower|, |upper| of a prismatic chain joint [m].
MAX_LIMIT_M = 1e3
_LINK_TAG = re.compile(rb"<link[\s/>]")

_MODELS: OrderedDict[tuple[str, str], UrdfModel] = OrderedDict()
#: The environment variable that turns the disk cache off (``0``).
CACHE_SWITCH = "IKBENCH_URDF_CACHE"
#: Files the disk cache keeps at most (the oldest go first; each a few kB).
CACHE_FILES = 256
#: This module's source, part of every disk cache key: a model written by other code is not
#: read back (computed on first use).
_CODE_KEY: list[str] = []


@dataclass(frozen=True, eq=False)
class UrdfJoint:
    """One ``<joint>`` of a URDF, in its units.

    Attributes:
        name: the joint's name.
        type: ``revolute``, ``continuous``, ``prismatic``, ``fixed``, ``floating`` or
            ``planar``.
        parent: the parent link.
        child: the child link.
        origin: (4, 4) the child's frame in the parent's at joint value 0 [m]; identity when
            the joint has no ``<origin>``.
        axis: (3,) the axis as written (not normalised); (1, 0, 0) when none is given.
        lower: lower limit [rad or m]; -inf for a continuous joint or one without ``<limit>``
            (0 where ``<limit>`` gives no ``lower``, as the URDF specification says).
        upper: upper limit [rad or m]; +inf as ``lower``.
        velocity: velocity limit [rad/s or m/s] as written; NaN when the joint gives none.
        mimic: the joint this one mimics (its ``<mimic joint=...>``), else None.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    velocity: float
    mimic: str | None = None

    @property
    def movable(self) -> bool:
        """True for revolute, continuous and prismatic joints."""
        return self.type in MOVABLE_TYPES


@dataclass(frozen=True, eq=False)
class UrdfCollision:
    """One ``<collision>`` element of a link.

    Attributes:
        link: the link it belongs to.
        kind: ``box``, ``cylinder``, ``sphere`` or ``mesh`` ("" when it has no geometry).
        origin: (4, 4) its frame in the link's [m].
        mesh: the mesh's file name as written (``package://`` URIs too), else None.
    """

    link: str
    kind: str
    origin: np.ndarray
    mesh: str | None = None


@dataclass(frozen=True, eq=False)
class UrdfModel:
    """A URDF file as yourdfpy parsed it (read-only; see the module docstring).

    Attributes:
        path: the URDF file.
        sha256: SHA-256 of the file's bytes (the cache key, with the path).
        name: the ``<robot>`` name.
        links: the link names, in file order.
        joints: the joints, in file order.
        root_link: the first link that is no joint's child.
        collisions: the links' ``<collision>`` elements, in file order.
    """

    path: Path
    sha256: str
    name: str
    links: tuple[str, ...]
    joints: tuple[UrdfJoint, ...]
    root_link: str
    collisions: tuple[UrdfCollision, ...]
    _data: bytes = field(repr=False)
    #: yourdfpy's tree, once parsed (empty in a model read from the disk cache).
    _trees: list[Any] = field(default_factory=list, repr=False)
    #: :meth:`to_xml`'s texts, by its arguments (kept in the disk cache with the model).
    _xml: dict[tuple, str] = field(default_factory=dict, repr=False)
    #: Kept on disk (a file that parsed with a warning is not: its warnings are said again).
    _cacheable: bool = field(default=False, repr=False)

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without yourdfpy's tree (reading it back would import yourdfpy)."""
        return {**self.__dict__, "_trees": []}

    @property
    def _tree(self) -> yourdfpy.Robot:
        """yourdfpy's tree of the file (parsed from the same bytes on first use)."""
        if not self._trees:
            self._trees.append(_yourdfpy_urdf(self._data).robot)
        return self._trees[0]

    def joint(self, name: str) -> UrdfJoint:
        """The joint called ``name`` (KeyError when there is none)."""
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise KeyError(name)

    def velocity_limits(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """(len(names),) the joints' velocity limits [rad/s or m/s]; NaN where a joint gives
        none or a non-positive one."""
        values = np.array([self.joint(name).velocity for name in names], dtype=float)
        return np.where(values > 0, values, math.nan)

    def path_between(self, base_link: str, end_link: str) -> tuple[UrdfJoint, ...]:
        """The joints from ``base_link`` down to ``end_link``, base first (fixed ones too).

        Raises:
            LookupError: ``end_link`` is not below ``base_link`` (or either is no link).
        """
        by_child = {j.child: j for j in self.joints}
        path, link = [], end_link
        while link != base_link:
            joint = by_child.get(link)
            if joint is None:
                raise LookupError(f"{end_link!r} is not below {base_link!r} in {self.path.name}")
            path.append(joint)
            link = joint.parent
        return tuple(reversed(path))

    def end_frame_candidates(self, base_link: str | None = None) -> tuple[str, ...]:
        """The links below ``base_link`` (default: the root) an end frame is likely to be:
        leaf links (no joint's parent) first, then links with a tool-like name
        (:data:`TOOL_WORDS`), each in file order."""
        below, frontier = [], [base_link or self.root_link]
        while frontier:
            parent = frontier.pop(0)
            children = [j.child for j in self.joints if j.parent == parent]
            below += children
            frontier += children
        order = {name: k for k, name in enumerate(self.links)}
        below.sort(key=lambda name: order.get(name, len(order)))
        parents = {j.parent for j in self.joints}
        leaves = [name for name in below if name not in parents]
        tools = [name for name in below if name not in leaves and tool_like(name)]
        return tuple(leaves + tools)

    def candidates_text(self, base_link: str | None = None) -> str:
        """``"candidates (leaf links first, then tool-like names): a, b"``: the links of
        :meth:`end_frame_candidates`, for an error that asks for an end frame."""
        found = self.end_frame_candidates(base_link)
        listed = ", ".join(found) if found else f"none below {base_link or self.root_link!r}"
        return f"candidates (leaf links first, then tool-like names): {listed}"

    def to_yourdfpy(self, **options: Any) -> yourdfpy.URDF:
        """A ``yourdfpy.URDF`` of a copy of the model (the caller may change it), built with
        ``options`` (yourdfpy's: ``build_scene_graph``, ``load_meshes``, ``mesh_dir``,
        ``filename_handler``, ...): the viewer's scene graph."""
        import yourdfpy

        return yourdfpy.URDF(robot=copy.deepcopy(self._tree), **options)

    def to_xml(self, *, visuals: bool = False, collisions: bool = True,
               fixed: Mapping[str, float] | None = None,
               continuous_limit: float | None = None, unit_axes: bool = False) -> str:
        """The URDF text of the model, written by yourdfpy, with these edits.

        Args:
            visuals: keep the ``<visual>`` elements (and the ``<material>`` elements).
            collisions: keep the ``<collision>`` elements.
            fixed: joints made fixed, name -> value [rad or m]: the motion at that value is
                folded into the joint's origin, and its axis, limit and dynamics go.
            continuous_limit: when given, continuous joints are written as revolute joints
                with limits -value..value [rad] (their effort and velocity kept, 0 if none).
            unit_axes: write every joint axis normalised.

        Fixed joints are written without an axis (ikpy warns about one). A text written once
        is kept with the model, on disk too (see the module docstring).
        """
        held = dict(fixed or {})
        key = (visuals, collisions, tuple(sorted(held.items())), continuous_limit, unit_axes)
        if key not in self._xml:
            self._xml[key] = self._written(visuals, collisions, held, continuous_limit,
                                           unit_axes)
            if self._cacheable:
                _write_cached(_cache_file((str(self.path), self.sha256)), self)
        return self._xml[key]

    def _written(self, visuals: bool, collisions: bool, held: dict[str, float],
                 continuous_limit: float | None, unit_axes: bool) -> str:
        """:meth:`to_xml`'s text, written by yourdfpy."""
        import yourdfpy

        joints = [_edited(j, held, continuous_limit, unit_axes) for j in self._tree.joints]
        links = [replace(link, visuals=link.visuals if visuals else [],
                         collisions=link.collisions if collisions else [])
                 for link in self._tree.links]
        robot = replace(self._tree, links=links, joints=joints,
                        materials=self._tree.materials if visuals else [])
        writer = yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False,
                               filename_handler=yourdfpy.filename_handler_null)
        tree = writer.write_xml()
        for origin in tree.iter("origin"):  # rpy from a matrix may hold -0.0 for a written 0
            for key in ("xyz", "rpy"):
                origin.set(key, " ".join(repr(float(v) + 0.0) for v in origin.get(key).split()))
        out = io.BytesIO()
        tree.write(out, xml_declaration=True)
        return out.getvalue().decode("ascii")


def with_fixed_frame(urdf_text: str, name: str, parent: str, rotation: np.ndarray) -> str:
    """A URDF text (written by :meth:`UrdfModel.to_xml`) with one more link ``name`` fixed
    to ``parent`` at its origin, rotated by ``rotation`` (3, 3): a frame a library can name
    (RangedIK's end link with the pointing axis as its z). Read and written by yourdfpy."""
    import yourdfpy

    tree = yourdfpy.URDF.load(io.BytesIO(urdf_text.encode()), build_scene_graph=False,
                              load_meshes=False, filename_handler=yourdfpy.filename_handler_null)
    origin = np.eye(4)
    origin[:3, :3] = rotation
    robot = tree.robot
    robot = replace(robot, links=[*robot.links, yourdfpy.Link(name=name)],
                    joints=[*robot.joints, yourdfpy.Joint(name=f"{name}_joint", type="fixed",
                                                          parent=parent, child=name,
                                                          origin=origin)])
    writer = yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False,
                           filename_handler=yourdfpy.filename_handler_null)
    out = io.BytesIO()
    writer.write_xml().write(out, xml_declaration=True)
    return out.getvalue().decode("ascii")


def _edited(joint: yourdfpy.Joint, fixed: dict[str, float], continuous_limit: float | None,
            unit_axes: bool) -> yourdfpy.Joint:
    """A copy of a yourdfpy joint with the edits of :meth:`UrdfModel.to_xml`."""
    if joint.name in fixed and joint.type in MOVABLE_TYPES:
        value = float(fixed[joint.name])
        origin = _origin(joint)
        if value:
            origin = origin @ _motion(joint.type, _unit(joint.axis), value)
        return replace(joint, type="fixed", origin=origin, axis=None, limit=None,
                       dynamics=None, mimic=None, safety_controller=None, calibration=None)
    if joint.type == "fixed":
        return replace(joint, axis=None)
    if joint.type == "continuous" and continuous_limit is not None:
        import yourdfpy

        old = joint.limit
        limit = yourdfpy.Limit(
            effort=0.0 if old is None or old.effort is None else old.effort,
            velocity=0.0 if old is None or old.velocity is None else old.velocity,
            lower=-float(continuous_limit), upper=float(continuous_limit))
        joint = replace(joint, type="revolute", limit=limit)
    if unit_axes and joint.axis is not None:
        joint = replace(joint, axis=_unit(joint.axis))
    return joint


def _origin(joint: yourdfpy.Joint) -> np.ndarray:
    """(4, 4) a copy of the joint's origin (identity when it has none)."""
    return np.eye(4) if joint.origin is None else np.array(joint.origin, dtype=float)


def _unit(axis: np.ndarray | None) -> np.ndarray:
    """``axis`` normalised ((1, 0, 0) for None; unchanged when zero)."""
    values = np.array([1.0, 0.0, 0.0] if axis is None else axis, dtype=float)
    norm = float(np.linalg.norm(values))
    return values / norm if norm > 0 else values


def _motion(kind: str, axis: np.ndarray, value: float) -> np.ndarray:
    """(4, 4) the motion of a joint of ``kind`` about/along a unit ``axis`` at ``value``
    [rad or m]."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    if kind == "prismatic":
        T[:3, 3] = axis * value
    else:
        T[:3, :3] = Rotation.from_rotvec(axis * value).as_matrix()
    return T


def load_urdf_model(path: str | Path) -> UrdfModel:
    """The :class:`UrdfModel` of a URDF file (cached per file and content).

    Raises:
        InputError: the file cannot be read or is no URDF yourdfpy can parse (one line).
    """
    path = Path(path).resolve()
    try:
        size = path.stat().st_size
        if size > MAX_URDF_BYTES:
            raise InputError(f"cannot read URDF {str(path)!r}: it is {size / 1e6:.1f} MB; "
                             f"the largest URDF read is {MAX_URDF_BYTES / 1e6:.0f} MB")
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read URDF {str(path)!r}: {exc}") from None
    links = len(_LINK_TAG.findall(data))
    if links > MAX_LINKS:
        raise InputError(f"cannot read URDF {str(path)!r}: it has {links:,} <link> elements; "
                         f"the most a URDF read may have is {MAX_LINKS:,}")
    key = (str(path), hashlib.sha256(data).hexdigest())
    if key in _MODELS:
        _MODELS.move_to_end(key)
        return _MODELS[key]
    stored = _cache_file(key)
    model = _read_cached(stored, key)
    if model is None:
        model = _parse(path, key[1], data, stored)
    _MODELS[key] = model
    while len(_MODELS) > CACHE_SIZE:
        _MODELS.popitem(last=False)
    return model


class _Errors(logging.Handler):
    """Collects what yourdfpy logs while it parses (it logs a malformed file's XML error,
    then parses what it can recover)."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def cache_folder() -> Path | None:
    """Where parsed models are kept between processes (see the module docstring); None when
    the cache is off."""
    if os.environ.get(CACHE_SWITCH, "1") == "0":
        return None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ikbench" / "urdf"


def _cache_file(key: tuple[str, str]) -> Path | None:
    """The disk cache's file of a (path, sha256) key, or None when the cache is off."""
    folder = cache_folder()
    if folder is None:
        return None
    if not _CODE_KEY:  # this module's source and the yourdfpy that writes to_xml's texts
        from importlib.metadata import PackageNotFoundError, version

        try:
            writer = version("yourdfpy")
        except PackageNotFoundError:
            writer = "none"
        _CODE_KEY.append(hashlib.sha256(Path(__file__).read_bytes()).hexdigest() + writer)
    name = hashlib.sha256("\n".join((_CODE_KEY[0], *key)).encode()).hexdigest()
    return folder / f"{name}.pickle"


def _read_cached(stored: Path | None, key: tuple[str, str]) -> UrdfModel | None:
    """The model kept in ``stored``, or None (none there, unreadable, or not this key's)."""
    if stored is None or not stored.is_file():
        return None
    try:
        model = pickle.loads(stored.read_bytes())
    except Exception:  # a partial or foreign file: parse again (and write it anew)
        return None
    if not isinstance(model, UrdfModel) or (str(model.path), model.sha256) != key:
        return None
    return model


def _write_cached(stored: Path | None, model: UrdfModel) -> None:
    """Keep ``model`` in ``stored`` (written whole or not at all; a cache that cannot be
    written is skipped)."""
    if stored is None:
        return
    try:
        stored.parent.mkdir(parents=True, exist_ok=True)
        partial = stored.with_suffix(f".{os.getpid()}.tmp")
        partial.write_bytes(pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL))
        os.replace(partial, stored)
        kept = sorted(stored.parent.glob("*.pickle"), key=lambda f: f.stat().st_mtime)
        for old in kept[:max(0, len(kept) - CACHE_FILES)]:
            old.unlink(missing_ok=True)
    except OSError:  # includes a file another process removed while this one listed it
        pass


def _yourdfpy_urdf(data: bytes) -> yourdfpy.URDF:
    """yourdfpy's parse of a URDF's bytes (no scene graph, no meshes)."""
    import yourdfpy

    return yourdfpy.URDF.load(io.BytesIO(data), build_scene_graph=False, load_meshes=False,
                              filename_handler=yourdfpy.filename_handler_null)


def _parse(path: Path, digest: str, data: bytes, stored: Path | None = None) -> UrdfModel:
    """Parse and check a URDF's bytes (see the module docstring); a model that parsed
    without a warning is kept in ``stored``."""
    import yourdfpy

    logger = logging.getLogger(yourdfpy.URDF.__module__)
    errors, propagate = _Errors(), logger.propagate
    logger.addHandler(errors)
    logger.propagate = False
    where = f"cannot read URDF {str(path)!r}"
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        try:
            urdf = _yourdfpy_urdf(data)
        except Exception as exc:  # yourdfpy raises what its parsing meets (KeyError, ...)
            reason = (errors.messages[0] if errors.messages
                      else f"an element lacks its {exc} attribute" if isinstance(exc, KeyError)
                      else f"not a URDF yourdfpy can read ({type(exc).__name__}: {exc})")
            raise InputError(f"{where}: {_one_line(reason)}{_warned(warned)}") from None
        finally:
            logger.removeHandler(errors)
            logger.propagate = propagate
    if errors.messages:
        raise InputError(f"{where}: {_one_line(errors.messages[0])}{_warned(warned)}")
    tree = urdf.robot
    try:
        joints = tuple(_joint(j) for j in tree.joints)
        _check(tree, joints, f"robot: {path.name}", data)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: {_one_line(str(exc))}{_warned(warned)}") from None
    except InputError as exc:
        raise InputError(f"{exc}{_warned(warned)}") from None
    for record in warned:  # an accepted file: what the parser said, said as it would have
        warnings.warn_explicit(record.message, record.category, record.filename, record.lineno)
    links = tuple(link.name for link in tree.links)
    children = {j.child for j in joints}
    root = next((name for name in links if name not in children), "")
    model = UrdfModel(path=path, sha256=digest, name=str(tree.name), links=links,
                      joints=joints, root_link=root,
                      collisions=tuple(_collision(link.name, c) for link in tree.links
                                       for c in link.collisions),
                      _data=data, _trees=[tree], _cacheable=not warned)
    if model._cacheable:
        _write_cached(stored, model)
    return model


def link_words(link: str) -> list[str]:
    """The words of a link name, lower case: split at non-letters and at lower-to-upper case
    changes (``CameraLeftEye_frame`` -> camera, left, eye, frame)."""
    words = re.split(r"[^a-z]+", re.sub(r"([a-z])([A-Z])", r"\1_\2", link).lower())
    return [word for word in words if word]


def tool_like(link: str) -> bool:
    """True when a word of ``link`` (:func:`link_words`) starts or ends with a tool word
    (``ee`` only starts one: ``eef``, not ``knee``)."""
    return any(word.startswith(tool) or (len(tool) > 2 and word.endswith(tool))
               for word in link_words(link) for tool in TOOL_WORDS)


def _check(tree: yourdfpy.Robot, joints: tuple[UrdfJoint, ...], where: str,
           data: bytes = b"") -> None:
    """InputError, one line starting with ``where``, naming the first joint or link of a
    parsed URDF that breaks a rule of the module docstring."""
    links = [str(link.name) for link in tree.links]
    for kind, names in (("link", links), ("joint", [j.name for j in joints])):
        counts = Counter(names)
        twice = next((n for n in names if counts[n] > 1), None)
        if twice is not None:
            raise InputError(f"{where}: {kind} {twice!r} is defined {counts[twice]} "
                             f"times; {kind} names must be unique")
    known = frozenset(links)
    for raw, joint in zip(tree.joints, joints):
        _check_joint(raw, joint, links, f"{where}: joint {joint.name!r}", data, known)
    _check_tree(links, joints, where)


def _check_joint(raw: yourdfpy.Joint, joint: UrdfJoint, links: list[str], where: str,
                 data: bytes = b"", known: frozenset[str] | None = None) -> None:
    known = frozenset(links) if known is None else known
    for role in ("parent", "child"):
        if getattr(joint, role) not in known:
            raise InputError(f"{where} names the {role} link {getattr(joint, role)!r}, which "
                             f"the URDF does not define; links: {', '.join(links)}")
    if joint.type not in JOINT_TYPES:
        raise InputError(f"{where} has type {joint.type!r}; allowed: {', '.join(JOINT_TYPES)}")
    limit = raw.limit
    if joint.type in LIMITED_TYPES and limit is None:
        raise InputError(f"{where} is {joint.type} and has no <limit>; a revolute or "
                         'prismatic joint needs <limit lower="..." upper="..." effort="..." '
                         'velocity="..."/> (a revolute joint without limits is type="continuous")')
    if limit is not None:
        for attribute in ("effort", "velocity", "lower", "upper"):
            value = getattr(limit, attribute)
            if value is None and attribute in ("effort", "velocity"):
                raise InputError(f"{where}: its <limit> has no {attribute}; a <limit> needs "
                                 "effort and velocity (lower and upper default to 0)")
            if value is not None and not math.isfinite(value):
                raise InputError(f'{where}: <limit {attribute}="{value}"> must be a finite '
                                 "number")
        if joint.type in LIMITED_TYPES and joint.lower > joint.upper:
            raise InputError(f'{where}: <limit lower="{joint.lower:g}" upper='
                             f'"{joint.upper:g}">: lower must not be above upper')
    if joint.type in AXIS_TYPES and (joint.axis.shape != (3,)
                                     or not np.all(np.isfinite(joint.axis))
                                     or not np.any(joint.axis)):
        xyz = " ".join(f"{v:g}" for v in joint.axis)
        raise InputError(f'{where}: <axis xyz="{xyz}"> is no direction; give three finite '
                         'numbers, not all zero (e.g. xyz="0 0 1")')
    if not np.all(np.isfinite(joint.origin)):
        raise InputError(f"{where}: its <origin{_origin_text(data, joint.name)}> holds a "
                         "number that is not finite; xyz and rpy are three finite numbers each")


def _check_tree(links: list[str], joints: tuple[UrdfJoint, ...], where: str) -> None:
    """One root link, one parent joint per link, every link reached from the root."""
    parent_joint: dict[str, str] = {}
    for joint in joints:
        if joint.child in parent_joint:
            raise InputError(f"{where}: link {joint.child!r} is the child of joints "
                             f"{parent_joint[joint.child]!r} and {joint.name!r}; a link has "
                             "one parent joint (a URDF is a tree)")
        parent_joint[joint.child] = joint.name
    roots = [name for name in links if name not in parent_joint]
    if len(roots) > 1:
        raise InputError(f"{where}: links {', '.join(map(repr, roots))} are all roots (no "
                         f"joint's child); a URDF has one root link: join {roots[1]!r} to "
                         "the tree with a joint")
    children: dict[str, list[str]] = {}
    for joint in joints:
        children.setdefault(joint.parent, []).append(joint.child)
    reached, frontier = set(roots), list(roots)
    while frontier:
        for child in children.get(frontier.pop(), ()):
            if child not in reached:
                reached.add(child)
                frontier.append(child)
    loop = [name for name in links if name not in reached]
    if loop:
        raise InputError(f"{where}: links {', '.join(map(repr, loop))} form a loop of joints "
                         f"{', '.join(repr(parent_joint[n]) for n in loop)} that no root "
                         "reaches; a URDF is a tree with one root link")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _warned(records: list[warnings.WarningMessage]) -> str:
    """``" (while parsing, trimesh warned: invalid value encountered in sin; ...)"``: the
    warnings the parser raised, for the end of the line that refuses the file ("" if none)."""
    said: dict[str, list[str]] = {}
    for record in records:
        module = Path(record.filename).parent.name if record.filename else "the parser"
        texts = said.setdefault(module, [])
        if _one_line(str(record.message)) not in texts:
            texts.append(_one_line(str(record.message)))
    parts = [f"{module} warned: {', '.join(texts)}" for module, texts in said.items()]
    return f" (while parsing, {'; '.join(parts)})" if parts else ""


def _origin_text(data: bytes, joint: str) -> str:
    """``' xyz="0 0 0.2" rpy="0 inf 0"'``: the attributes of a joint's ``<origin>`` as
    written (for an error naming the value; "" when they cannot be found)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(data)
    except ET.ParseError:
        return ""
    for element in root.iter("joint"):
        origin = element.find("origin")
        if element.get("name") == joint and origin is not None:
            return "".join(f' {k}="{origin.get(k)}"' for k in ("xyz", "rpy")
                           if origin.get(k) is not None)
    return ""


def _joint(joint: yourdfpy.Joint) -> UrdfJoint:
    limit = joint.limit
    if joint.type == "continuous" or limit is None:
        lower, upper = -math.inf, math.inf
    else:
        lower = 0.0 if limit.lower is None else float(limit.lower)
        upper = 0.0 if limit.upper is None else float(limit.upper)
    velocity = math.nan if limit is None or limit.velocity is None else float(limit.velocity)
    axis = np.array([1.0, 0.0, 0.0] if joint.axis is None else joint.axis, dtype=float)
    origin = _origin(joint)
    origin.setflags(write=False)
    axis.setflags(write=False)
    mimic = None if joint.mimic is None else str(joint.mimic.joint)
    return UrdfJoint(name=str(joint.name), type=str(joint.type), parent=str(joint.parent),
                     child=str(joint.child), origin=origin, axis=axis, lower=lower,
                     upper=upper, velocity=velocity, mimic=mimic)


def _collision(link: str, collision: yourdfpy.Collision) -> UrdfCollision:
    geometry = collision.geometry
    kinds = ("box", "cylinder", "sphere", "mesh")
    kind = next((k for k in kinds if geometry is not None and getattr(geometry, k) is not None),
                "")
    origin = np.eye(4) if collision.origin is None else np.array(collision.origin, dtype=float)
    origin.setflags(write=False)
    mesh = geometry.mesh.filename if kind == "mesh" else None
    return UrdfCollision(link=link, kind=kind, origin=origin, mesh=mesh)

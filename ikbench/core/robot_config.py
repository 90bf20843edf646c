"""A robot's config (``urdf/<name>.toml``) as typed, frozen fields: :class:`RobotConfig`.

Built once where the config is loaded (:func:`ikbench.core.robot.load_robot`); every other
module reads its attributes, never a key of a raw dict (``tests/test_architecture.py``).
Unknown keys and values of the wrong type are refused with one line naming the key.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from ikbench.core.errors import InputError, refuse_unknown_keys

#: Keys a robot config may hold (a typo would otherwise be ignored silently).
CONFIG_KEYS = ("name", "description", "source", "urdf", "base_link", "end_frame",
               "pointing_axis", "joints", "motor_map", "hardware", "targets", "frame",
               "letters", "batch", "locked", "validity_limits", "collision")


def _check(value: Any, kinds: tuple[type, ...], what: str, where: str) -> Any:
    if value is not None and not isinstance(value, kinds):
        raise InputError(f"{where}: {what} must be {' or '.join(k.__name__ for k in kinds)}, "
                         f"not {type(value).__name__}")
    return value


def _table(value: Any, what: str, where: str, allowed: tuple[str, ...]) -> dict:
    _check(value, (dict,), what, where)
    refuse_unknown_keys(value or {}, allowed, f"{where}: [{what}]")
    return dict(value or {})


@dataclass(frozen=True)
class TargetsSection:
    """``[targets]``: the robot's default targets file (next to the config) and its name."""

    file: str | None = None
    name: str | None = None


@dataclass(frozen=True)
class FrameSection:
    """``[frame]``: how reports name and draw the base frame."""

    name: str | None = None
    axis_labels: tuple[str, ...] | None = None
    view: tuple[float, ...] | None = None  # elevation, azimuth [deg]


@dataclass(frozen=True)
class LettersSection:
    """``[letters]``: the letter experiment's start pose [pose units] and plane axes."""

    start_pose: tuple[float, ...] | None = None
    plane_u: tuple[float, ...] | None = None
    plane_v: tuple[float, ...] | None = None


def _section(cls: type, value: Any, what: str, where: str) -> Any:
    names = tuple(f.name for f in fields(cls))
    table = _table(value, what, where, names)
    out = {}
    for key, item in table.items():
        if isinstance(item, list):
            item = tuple(item)
        _check(item, (str,) if key in ("file", "name") else (tuple,), f"{what}.{key}", where)
        out[key] = item
    return cls(**out)


@dataclass(frozen=True)
class RobotConfig:
    """A robot's config: one field per key of :data:`CONFIG_KEYS`, plus the file it came
    from (``config_path``; None for a bare URDF or a description package)."""

    config_path: Path | None = None
    name: str | None = None
    description: str = ""
    source: str = ""
    urdf: str | None = None
    base_link: str | None = None
    end_frame: str | None = None
    pointing_axis: tuple[float, ...] | None = None
    joints: tuple[str, ...] | None = None
    motor_map: str | None = None
    hardware: str | None = None
    targets: TargetsSection = field(default_factory=TargetsSection)
    frame: FrameSection = field(default_factory=FrameSection)
    letters: LettersSection = field(default_factory=LettersSection)
    batch: dict[str, Any] = field(default_factory=dict)  # checked by studies.batch
    locked: dict[str, Any] = field(default_factory=dict)
    validity_limits: dict[str, Any] = field(default_factory=dict)
    collision: str | None = None

    @property
    def folder(self) -> Path | None:
        """The folder the config's relative file names start from (None: no config file)."""
        return self.config_path.parent if self.config_path is not None else None

    @classmethod
    def from_dict(cls, config: dict[str, Any], where: str,
                  config_path: Path | None = None) -> RobotConfig:
        """The typed config of a parsed file; InputError naming the key on a bad one."""
        refuse_unknown_keys(config, CONFIG_KEYS, where)
        for key in ("name", "description", "source", "urdf", "base_link", "end_frame",
                    "motor_map", "hardware", "collision"):
            _check(config.get(key), (str,), key, where)
        for key in ("pointing_axis", "joints"):
            _check(config.get(key), (list, tuple), key, where)
        for key in ("batch", "locked", "validity_limits"):
            _check(config.get(key), (dict,), key, where)
        axis = config.get("pointing_axis")
        joints = config.get("joints")
        return cls(config_path=config_path, name=config.get("name"),
                   description=config.get("description") or "",
                   source=config.get("source") or "", urdf=config.get("urdf"),
                   base_link=config.get("base_link"), end_frame=config.get("end_frame"),
                   pointing_axis=tuple(axis) if axis is not None else None,
                   joints=tuple(joints) if joints is not None else None,
                   motor_map=config.get("motor_map"), hardware=config.get("hardware"),
                   targets=_section(TargetsSection, config.get("targets"), "targets", where),
                   frame=_section(FrameSection, config.get("frame"), "frame", where),
                   letters=_section(LettersSection, config.get("letters"), "letters", where),
                   batch=dict(config.get("batch") or {}),
                   locked=dict(config.get("locked") or {}),
                   validity_limits=dict(config.get("validity_limits") or {}),
                   collision=config.get("collision"))

"""The Stabilizer protocol and the stabilizer registry.

A stabilizer sits between the scenario and the controller: each tick it reads the `Measurement` (what the robot's
sensors give), the scenario's `References` and the controller's `ModelFeedback` (its model configuration, contacts
and last QP wrenches), and returns corrected `References`. It never reads or writes a controller's attributes:
everything it changes travels in the references (the CoM, task targets, `wrench_targets`, `contact_poses`).

A task set selects one with its `stabilizer:` section, dispatched on `type:` (`dcm`: the DCM PI + CoM admittance
of the position-controlled schemes, paper 000 Eq. 2-4; `force`: the force-based teleoperation stabilizer, paper
004 Eq. 2-7). Each class parses its own section into a frozen spec.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..catalogue import BUILTIN_STABILIZERS  # the built-ins: name -> "module:Attr", imported when first used
from ..config import Section
from ..errors import ConfigError, UnknownNameError
from ..types import Measurement, ModelFeedback, References

__all__ = ["BUILTIN_STABILIZERS", "MissingReferenceError", "Stabilizer", "StabilizerConfig", "available_stabilizers",
           "make_stabilizer", "parse_stabilizer", "register_stabilizer", "stabilizer_class"]


class MissingReferenceError(ConfigError):
    """A scenario does not give a reference a stabilizer needs (e.g. a ZMP plan for the DCM stabilizer)."""


class Stabilizer(ABC):
    """A feedback law correcting references from measurements (module docstring).

    Class attributes: `type` (the YAML `stabilizer.type`), `requires` (the `References` fields the scenario must
    give, checked at reset), `LOG_LABELS` (components of the per-tick log channel `stabilizer`). `log` holds the
    last tick's values (NaN where a law did not run).
    """

    type: ClassVar[str] = ""
    requires: ClassVar[tuple[str, ...]] = ()
    LOG_LABELS: ClassVar[tuple[str, ...]] = ()

    log: np.ndarray

    @classmethod
    @abstractmethod
    def parse(cls, sec: Section) -> Any:
        """The frozen spec of this stabilizer from its task-set section (without `type`); errors name the key."""

    @abstractmethod
    def reset(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> None:
        """Start a run: `refs` are the scenario's first references, `feedback` the controller's model at rest."""

    @abstractmethod
    def correct(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> References:
        """The references of this tick, corrected (the same object when nothing changes)."""

    def check(self, refs: References) -> None:
        """Raise `MissingReferenceError` if the scenario's references lack a field this stabilizer needs."""
        missing = refs.missing(self.requires)
        if missing:
            raise MissingReferenceError(
                f"the '{self.type}' stabilizer needs the scenario to give {' and '.join(repr(m) for m in missing)} "
                f"references, and it gives none (give the scenario a {missing[0]} plan, or use a task set without "
                "this stabilizer)", key="stabilizer")


_TYPES: dict[str, type[Stabilizer]] = {}
"""Stabilizer types registered in Python (`register_stabilizer`), by name."""
_LOADED: dict[str, type[Stabilizer]] = {}


def register_stabilizer(cls: type[Stabilizer]) -> type[Stabilizer]:
    """Class decorator: make `cls` selectable as `stabilizer: {type: <cls.type>}` in task sets (a built-in's type
    stays the built-in's)."""
    if not cls.type:
        raise TypeError(f"{cls.__name__} has no `type`")
    _TYPES[cls.type] = cls
    return cls


def stabilizer_class(name: str) -> type[Stabilizer]:
    """The class of a stabilizer type (only its own module is imported); KeyError when unknown."""
    if name in BUILTIN_STABILIZERS:
        cls = _LOADED.get(name)
        if cls is None:
            from ..plugins import load

            cls = _LOADED[name] = load(BUILTIN_STABILIZERS[name])
        return cls
    return _TYPES[name]


def available_stabilizers() -> dict[str, type[Stabilizer]]:
    """Every stabilizer type by name: the built-in ones and those registered in Python."""
    out = dict(_TYPES)
    out.update({name: stabilizer_class(name) for name in BUILTIN_STABILIZERS})
    return dict(sorted(out.items()))


@dataclass(frozen=True)
class StabilizerConfig:
    """A task set's `stabilizer:` section: the registered `type` and its parsed `spec`."""

    type: str
    spec: Any


def parse_stabilizer(sec: Section) -> StabilizerConfig:
    """Parse a `stabilizer:` section (`type:` defaults to `dcm`, the paper's walking stabilizer)."""
    name = sec.str("type", "dcm")
    if name not in BUILTIN_STABILIZERS and name not in _TYPES:
        raise UnknownNameError("stabilizer type", name, available_stabilizers(), file=sec.file, key=sec.key("type"))
    return StabilizerConfig(name, stabilizer_class(name).parse(sec))


def make_stabilizer(config: StabilizerConfig, robot, dt: float) -> Stabilizer:
    """The stabilizer of a task set, for `robot` at control period `dt` [s]."""
    return stabilizer_class(config.type)(robot, config.spec, dt)

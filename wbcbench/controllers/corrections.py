"""Plan corrections: stages with one protocol that turn the plan's references into the ones a controller solves for.

Each tick a controller hands the scenario's `References` through its correction stages, in the order its task set
lists them, and solves for what comes out of the last one. A stage is a `Correction`:

* `type` (class attribute): its name in task sets, `corrections: [{type: <type>, ...}]`;
* `parse(sec)` (class method): its settings from its entry of the list (every key but `type` and `name`; unknown
  keys are errors naming file and key); `build(config, robot, dt)` (class method): the stage, by default
  `cls(config, robot, dt)`;
* `reset(ctx)`: at the controller's reset (`ctx.refs`: the first references, `ctx.feedback()` the model at rest);
* `apply(ctx) -> References`: this tick's references corrected (`ctx.refs`: the references corrected by the
  stages before it; return the same object when nothing changes);
* `status() -> dict`: counters for the run's summary (default none);
* `configuration(ctx, q) -> q` and `command(ctx, cmd) -> Command` (optional, default: unchanged): after the
  references, the two places a stage may act on the joints themselves: the configuration a torque-mode
  controller solves at (from the measured one) and the command a position scheme sends (after its solve), e.g.
  `hip_compensation`'s `target: hip_joint`;
* `LOG_LABELS` and `log`: when not empty, the stage logs `log` (an array of that length, written in place) every
  tick, as the controller's channel `correction_<name>` (the stabilizer stage's channel is `stabilizer`);
* `needs_integrated_model` (class attribute): the stage corrects towards what a position-controlled robot's
  integrated model needs; a controller without one (the inverse-dynamics controllers in torque mode, whose model is
  the measured state) leaves it out.

The context (`CorrectionContext`) carries the measurement `meas`, the plan's references `plan` (the scenario's,
before any stage), the references corrected so far `refs`, the controller's model configuration `q_model` (the
integrated one for position schemes, the measured one in torque mode) and `feedback()`, the controller's
`ModelFeedback` for `refs` (made on demand: call it only when the stage needs it). It is one object per controller,
updated in place each tick.

The built-in stages, in the order the task sets' old sections put them:

    plan_lead         controllers/plan_lead.py    the CoM and ZMP references led along the plan
    lift_off_wait     controllers/liftoff.py      a loaded leaving foot held in contact
    touchdown_search  controllers/touchdown.py    an unloaded landing foot kept descending
    base_feedback     estimation/base_feedback.py the plan mapped into the integrated model's world
    swing_tilt        controllers/swing_tilt.py   a swing foot turned against the stance leg's yield
    stabilizer        stabilizers/                any registered stabilizer (`law:`, default dcm) with its gains

A task set gives them either as the list `corrections:` (any order, any registered type, at most one stabilizer)
or as the sections `plan_lead:`, `lift_off_wait:`, `touchdown_search:`, `base_feedback:`, `swing_tilt:`,
`stabilizer:`, which are mapped onto the list in the order above; giving both is an error.

Types are found in `BUILTIN_CORRECTIONS` (name -> "module:Attr", imported when first used), then among the classes
registered in Python (`register_correction`), then among the installed packages' entry points of the group
`wbcbench.corrections` (wbcbench/plugins.py). docs/corrections.md shows a correction written outside the package.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, ClassVar

import numpy as np

from ..catalogue import BUILTIN_CORRECTIONS  # the built-ins: name -> "module:Attr", imported when first used
from ..config import Section
from ..errors import ConfigError, UnknownNameError
from ..types import Command, Measurement, ModelFeedback, References

if TYPE_CHECKING:
    from ..robots import Robot
    from ..stabilizers.base import Stabilizer

__all__ = ["BUILTIN_CORRECTIONS", "BaseFeedbackStage", "Correction", "CorrectionContext", "CorrectionSpec",
           "StabilizerStage", "available_corrections", "correction_class", "correction_plugin_errors",
           "parse_corrections", "parse_settings", "register_correction"]


GROUP = "wbcbench.corrections"


class CorrectionContext:
    """What a correction stage sees at a tick (module docstring): `meas`, `plan`, `refs`, `q_model`, `feedback()`.
    One per controller, its fields set in place each tick."""

    __slots__ = ("meas", "plan", "refs", "q_model", "_feedback")

    def __init__(self) -> None:
        self.meas: Measurement | None = None
        self.plan: References | None = None
        self.refs: References | None = None
        self.q_model: np.ndarray | None = None
        self._feedback: Callable[[References], ModelFeedback] | None = None

    @classmethod
    def of(cls, refs: References, meas: Measurement | None = None, q_model: np.ndarray | None = None,
           feedback: Callable[[References], ModelFeedback] | None = None) -> "CorrectionContext":
        """A context for one call of a stage outside a controller (`plan` and `refs` both `refs`)."""
        ctx = cls()
        ctx.meas, ctx.plan, ctx.refs, ctx.q_model, ctx._feedback = meas, refs, refs, q_model, feedback
        return ctx

    def feedback(self) -> ModelFeedback:
        """The controller's `ModelFeedback` for the references corrected so far (its model configuration,
        contacts and, for the inverse-dynamics controllers, the last solve's wrenches and contact placements)."""
        return self._feedback(self.refs)


class Correction(ABC):
    """A plan correction stage (module docstring). Subclass it, give it a `type`, and implement `apply`; the
    default constructor keeps `config`, `robot` and `dt` as attributes."""

    type: ClassVar[str] = ""
    needs_integrated_model: ClassVar[bool] = False
    LOG_LABELS: ClassVar[tuple[str, ...]] = ()

    log: np.ndarray

    def __init__(self, config: Any = None, robot: "Robot | None" = None, dt: float = 0.0):
        self.config = config
        self.robot = robot
        self.dt = dt

    @classmethod
    def parse(cls, sec: Section) -> Any:
        """The settings from the stage's task-set entry (`sec`, without `type` and `name`); default: none."""
        return None

    @classmethod
    def build(cls, config: Any, robot: "Robot", dt: float) -> "Correction":
        """The stage for `robot` at control period `dt` [s] with the parsed settings `config`."""
        return cls(config, robot, dt)

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        """Start a run (default: nothing)."""

    @abstractmethod
    def apply(self, ctx: CorrectionContext) -> References:
        """This tick's references, `ctx.refs` corrected (the same object when nothing changes)."""

    def status(self) -> dict:
        """Counters for the run's summary (default: none)."""
        return {}

    def configuration(self, ctx: CorrectionContext, q: np.ndarray) -> np.ndarray:
        """Torque mode: the configuration the controller solves at, from `q` (the measured one, after `apply` at
        this tick); return `q` itself when unchanged, a new array otherwise (never change `q` in place: it is the
        measurement's). Default: unchanged."""
        return q

    def command(self, ctx: CorrectionContext, cmd: "Command") -> "Command":
        """Position schemes: the command sent to the robot, from the controller's `cmd` (after its solve at this
        tick); return `cmd` itself when unchanged. Default: unchanged."""
        return cmd


@dataclass(frozen=True)
class CorrectionSpec:
    """One stage of a task set: its registered `type`, its parsed settings `config`, and its `name` (its log
    channel `correction_<name>`; default the type)."""

    type: str
    config: Any = None
    name: str = ""

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", self.type)


# ---------------------------------------------------------------------------------------------------- built-ins
class StabilizerStage(Correction):
    """The stage of a stabilizer (any `wbcbench.stabilizers` type): `check` and `reset` at the controller's reset,
    `correct` with the controller's model feedback each tick. Its entry: `{type: stabilizer, law: dcm, <gains>}`
    (`law` is the stabilizer's type, default dcm)."""

    type = "stabilizer"

    def __init__(self, stabilizer: "Stabilizer"):
        super().__init__()
        self.stabilizer = stabilizer
        self.LOG_LABELS = stabilizer.LOG_LABELS

    @classmethod
    def parse(cls, sec: Section):
        from ..stabilizers.base import StabilizerConfig, available_stabilizers

        types = available_stabilizers()
        law = sec.str("law", "dcm")
        if law not in types:
            raise UnknownNameError("stabilizer type", law, types, file=sec.file, key=sec.key("law"))
        return StabilizerConfig(law, types[law].parse(sec))

    @classmethod
    def build(cls, config, robot, dt) -> "StabilizerStage":
        from ..stabilizers.base import make_stabilizer

        return cls(make_stabilizer(config, robot, dt))

    @property
    def log(self) -> np.ndarray:
        return self.stabilizer.log

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self.stabilizer.check(ctx.refs)
        self.stabilizer.reset(ctx.meas, ctx.refs, ctx.feedback())

    def apply(self, ctx: CorrectionContext) -> References:
        refs = ctx.refs
        return self.stabilizer.correct(ctx.meas, refs, ctx._feedback(refs))


class BaseFeedbackStage(Correction):
    """The stage of the base feedback (`wbcbench.estimation.base_feedback.BaseFeedback`, kept as `base_feedback`):
    the plan mapped into the integrated model's world. Its entry: `{type: base_feedback, time_constant: 0.3,
    liftoff_blend: 0.3}`."""

    type = "base_feedback"
    needs_integrated_model = True

    def __init__(self, config, robot, dt):
        from ..estimation.base_feedback import BaseFeedback

        super().__init__(config, robot, dt)
        self.base_feedback = BaseFeedback(robot, dt, config)
        self._correct = self.base_feedback.correct

    @classmethod
    def parse(cls, sec: Section):
        from ..estimation.base_feedback import BaseFeedbackConfig

        return BaseFeedbackConfig(time_constant=sec.float("time_constant", 1.0, positive=True),
                                  liftoff_blend=sec.float("liftoff_blend", 0.0, min=0.0))

    def reset(self, ctx: CorrectionContext | None = None) -> None:
        self.base_feedback.reset()

    def apply(self, ctx: CorrectionContext) -> References:
        return self._correct(ctx.meas, ctx.refs, ctx.q_model)


def parse_settings(sec: Section, cls, required: tuple[str, ...] = (), upper: dict | None = None):
    """The settings `cls` (a dataclass of floats) from `sec`: each field a positive number, the dataclass's default
    when absent (unless `required`); `upper`: field -> (bound, message) for a field that must stay below a bound."""
    from dataclasses import fields

    values = {}
    for f in fields(cls):
        v = sec.float(f.name, ... if f.name in required else f.default, positive=True)
        if upper and f.name in upper and v >= upper[f.name][0]:
            raise sec.error(f.name, f"{upper[f.name][1]}, got {v}")
        values[f.name] = v
    return cls(**values)


# ---------------------------------------------------------------------------------------------------- registry
_REGISTERED: dict[str, type[Correction]] = {}
_LOADED: dict[str, type[Correction]] = {}


def register_correction(cls: type[Correction]) -> type[Correction]:
    """Class decorator: make `cls` usable as `corrections: [{type: <cls.type>}]` in task sets (for a class defined
    in a script or a test; a package declares an entry point of the group `wbcbench.corrections` instead)."""
    if not (isinstance(cls, type) and issubclass(cls, Correction)):
        raise TypeError(f"{cls!r} is not a Correction subclass")
    if not cls.type:
        raise TypeError(f"{cls.__name__} has no `type`")
    if cls.type in BUILTIN_CORRECTIONS:
        raise ValueError(f"correction type '{cls.type}' is a built-in's")
    _REGISTERED[cls.type] = cls
    return cls


def _builtin(name: str) -> type[Correction]:
    cls = _LOADED.get(name)
    if cls is None:
        module, attr = BUILTIN_CORRECTIONS[name].split(":")
        cls = _LOADED[name] = getattr(importlib.import_module(module), attr)
    return cls


def _plugins():
    from ..plugins import discover

    return discover(GROUP, set(BUILTIN_CORRECTIONS) | set(_REGISTERED), Correction)


def available_corrections() -> dict[str, str]:
    """Every usable correction type -> where it comes from ("module:Attr" for the built-ins, the module of a
    registered class, the distribution of a plugin); broken plugins are left out (`correction_plugin_errors`)."""
    out = dict(BUILTIN_CORRECTIONS)
    out.update({n: f"{c.__module__}:{c.__qualname__}" for n, c in _REGISTERED.items()})
    out.update({p.name: p.origin for p in _plugins() if p.error is None})
    return dict(sorted(out.items()))


def correction_plugin_errors() -> dict[str, str]:
    """name -> one-line message, for the correction plugins that cannot be used."""
    from ..plugins import message

    return {p.name: message(p) for p in _plugins() if p.error is not None}


def correction_class(name: str, *, file: str | None = None, key: str | None = None) -> type[Correction]:
    """The class of correction type `name`; an unknown name is an `UnknownNameError` listing the known ones, a
    broken plugin a `PluginError` (both naming `file` and `key`)."""
    if name in BUILTIN_CORRECTIONS:
        return _builtin(name)
    if name in _REGISTERED:
        return _REGISTERED[name]
    for p in _plugins():
        if p.name == name:
            if p.error is not None:
                from ..plugins import PluginError, message

                raise PluginError(message(p), file=file, key=key)
            return p.obj
    raise UnknownNameError("correction type", name, available_corrections(), file=file, key=key)


# ---------------------------------------------------------------------------------------------------- task sets
#: the task sets' sections of the built-in stages, in the order they are mapped onto the list
SECTIONS = ("plan_lead", "lift_off_wait", "touchdown_search", "base_feedback", "swing_tilt", "stabilizer")


def parse_corrections(sec: Section, key: str = "corrections") -> tuple[CorrectionSpec, ...]:
    """The list `corrections:` of a task set: each entry a mapping with `type` (a registered correction type),
    optional `name` (unique in the list; default the type) and the type's settings. At most one stabilizer."""
    out, names = [], {}
    raw = sec.list(key)
    for i, entry in enumerate(raw):
        e = Section(entry, sec.file, sec.key(f"{key}[{i}]"))
        if not isinstance(entry, dict):
            raise e.error(None, f"must be a mapping with `type:` (one of {', '.join(available_corrections())}), "
                                f"got {entry!r}")
        type_ = e.str("type")
        cls = correction_class(type_, file=sec.file, key=e.key("type"))
        if issubclass(cls, StabilizerStage) and any(s.type == "stabilizer" for s in out):
            raise e.error("type", "a task set has at most one stabilizer")
        name = e.str("name", type_)
        if name in names:
            raise e.error("name", f"'{name}' names entry {names[name]} too; give each stage of one type its own "
                                  "`name`")
        names[name] = i
        try:
            config = cls.parse(e)
        except ConfigError:  # already names file and key
            raise
        except (TypeError, ValueError) as exc:  # a plugin's settings class refusing a value
            raise e.error(None, str(exc)) from None
        e.finish()
        out.append(CorrectionSpec(type_, config, name))
    return tuple(out)


def specs_from_sections(spec) -> tuple[CorrectionSpec, ...]:
    """The stages of a task set given by its sections (`TaskSetSpec.plan_lead` ... `stabilizer`), in the order
    of `SECTIONS`."""
    return tuple(CorrectionSpec(name, getattr(spec, name)) for name in SECTIONS if getattr(spec, name) is not None)

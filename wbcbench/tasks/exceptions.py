"""Exceptions raised by the task library.

Every message names the task (type and name), the offending key, the value received and what is allowed,
so that a YAML loader can re-raise it with the file name prepended and nothing else to add.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["TaskConfigError", "UnknownNameError", "ReferenceNotSetError"]


class TaskConfigError(ValueError):
    """A task was given an invalid definition or input (wrong shape, negative gain, bad mask, ...).

    Attributes:
        owner: the task, e.g. ``"FrameTask 'waist'"``.
        key: the offending argument, e.g. ``"kp"`` or ``"mask"``.
    """

    def __init__(self, owner: str, key: str, message: str) -> None:
        self.owner = owner
        self.key = key
        super().__init__(f"{owner}: {key}: {message}")


class UnknownNameError(TaskConfigError):
    """A frame or joint name that the model does not have.

    Attributes:
        kind: ``"frame"`` or ``"joint"``.
        name: the name that was asked for.
        suggestions: the closest valid names (difflib), best first; may be empty.
        valid: every valid name of that kind, in model order.
    """

    def __init__(
        self, owner: str, key: str, kind: str, name: str, suggestions: Sequence[str], valid: Sequence[str]
    ) -> None:
        self.kind = kind
        self.name = name
        self.suggestions = tuple(suggestions)
        self.valid = tuple(valid)
        if self.suggestions:
            hint = "did you mean " + ", ".join(repr(s) for s in self.suggestions) + "?"
        else:
            shown = ", ".join(repr(s) for s in self.valid[:12])
            more = f", ... ({len(self.valid)} in all)" if len(self.valid) > 12 else ""
            hint = f"valid {kind} names: {shown}{more}"
        super().__init__(owner, key, f"unknown {kind} {name!r} in the model; {hint}")


class ReferenceNotSetError(RuntimeError):
    """A task was evaluated before its reference was set (call ``set_reference`` first)."""

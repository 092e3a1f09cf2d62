"""Exceptions raised by the task library.

Every message names the task (type and name), the offending key, the value received and what is allowed,
so that a YAML loader can re-raise it with the file name prepended and nothing else to add.
"""

from __future__ import annotations

from wbcbench.errors import UnknownNameError, WbcError  # noqa: F401  (UnknownNameError: the one of wbcbench)

__all__ = ["TaskConfigError", "UnknownNameError", "ReferenceNotSetError"]


class TaskConfigError(WbcError, ValueError):
    """A task was given an invalid definition or input (wrong shape, negative gain, bad mask, ...).

    Attributes:
        owner: the task, e.g. ``"FrameTask 'waist'"``.
        key: the offending argument, e.g. ``"kp"`` or ``"mask"``.
    """

    def __init__(self, owner: str, key: str, message: str) -> None:
        self.owner = owner
        self.key = key
        super().__init__(f"{owner}: {key}: {message}")


class ReferenceNotSetError(WbcError, RuntimeError):
    """A task was evaluated before its reference was set (call ``set_reference`` first)."""

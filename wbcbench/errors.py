"""Domain errors. Every user-facing failure is one of these: the CLI prints its message on one line."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class WbcError(Exception):
    """Base class for errors wbcbench reports to the user (one line, exit code 2)."""


class ConfigError(WbcError):
    """A configuration file or argument is invalid.

    The message names the file, the key and what is allowed.
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        where = ""
        if file:
            where = f"{file}: "
        if key:
            where += f"option {key}: " if key.startswith("--") else f"key '{key}': "
        super().__init__(one_line(where + message))
        self.file = file
        self.key = key


class UnknownNameError(ConfigError, ValueError):
    """A name (robot, scenario, controller, frame, joint...) that does not exist; the one such error of wbcbench
    (the task library raises it too, with the task as `owner`). `suggestions`: the closest valid names."""

    def __init__(self, kind: str, name: str, valid: Iterable[str], *, file: str | None = None,
                 key: str | None = None, owner: str | None = None, sort: bool = True):
        valid = sorted(valid) if sort else list(valid)
        close = difflib.get_close_matches(name, valid, n=3)
        hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
        listing = ", ".join(valid) if len(valid) <= 20 else ", ".join(valid[:20]) + f", ... ({len(valid)} in all)"
        prefix = f"{owner}: " if owner else ""
        super().__init__(f"{prefix}unknown {kind} '{name}'{hint}; known: {listing}", file=file, key=key)
        self.kind = kind
        self.name = name
        self.valid = valid
        self.suggestions = tuple(close)


class PlanningError(WbcError, ValueError):
    """A plan that cannot be made (footsteps out of reach, an infeasible centroidal QP, ...): raised by
    `wbcbench.planning`; the scenario that asked for the plan adds its file and key (the one conversion point)."""


class QPError(WbcError, ValueError):
    """An invalid QP (shapes, non-finite data, bounds in the wrong order): raised by `wbcbench.qp`."""


def one_line(text: str) -> str:
    """`text` on one line: control characters (a key named with a newline, say) shown escaped."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def did_you_mean(name: str, valid: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(valid), n=3)
    return f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""

"""Small helpers to read YAML into validated plain values, with errors naming file and key."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .errors import ConfigError


def load_yaml(path: str | Path) -> dict:
    """Read a YAML mapping; a missing file, bad syntax or a non-mapping top level is a ConfigError."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read file ({exc.strerror})", file=str(path)) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ConfigError(f"invalid YAML{at}: {getattr(exc, 'problem', exc)}", file=str(path)) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, got {type(data).__name__}", file=str(path))
    return data


class Section:
    """A view on one mapping of a config file that tracks the key path for error messages.

    `take` methods consume keys; `finish()` rejects any key left over (unknown keys are errors).
    """

    def __init__(self, data: Any, file: str | None, path: str = ""):
        if not isinstance(data, Mapping):
            raise ConfigError(f"must be a mapping, got {type(data).__name__}", file=file, key=path or None)
        self.data = dict(data)
        self.file = file
        self.path = path
        self._used: set[str] = set()

    def key(self, k: str) -> str:
        return f"{self.path}.{k}" if self.path else k

    def error(self, k: str | None, msg: str) -> ConfigError:
        return ConfigError(msg, file=self.file, key=self.key(k) if k else (self.path or None))

    def has(self, k: str) -> bool:
        return k in self.data

    def raw(self, k: str, default: Any = ..., ) -> Any:
        self._used.add(k)
        if k not in self.data:
            if default is ...:
                raise self.error(k, "is required")
            return default
        return self.data[k]

    def section(self, k: str, default: Any = ...) -> "Section":
        val = self.raw(k, default)
        return Section(val if val is not None else {}, self.file, self.key(k))

    def str(self, k: str, default: Any = ..., choices: Sequence[str] | None = None) -> str:
        val = self.raw(k, default)
        if not isinstance(val, str):
            raise self.error(k, f"must be a string, got {val!r}")
        if choices is not None and val not in choices:
            raise self.error(k, f"'{val}' is not allowed; allowed: {', '.join(choices)}")
        return val

    def float(self, k: str, default: Any = ..., *, min: float | None = None, max: float | None = None,
              positive: bool = False) -> float:
        val = self.raw(k, default)
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            raise self.error(k, f"must be a number, got {val!r}")
        val = float(val)
        if not np.isfinite(val):
            raise self.error(k, f"must be finite, got {val}")
        if positive and val <= 0:
            raise self.error(k, f"must be > 0, got {val}")
        if min is not None and val < min:
            raise self.error(k, f"must be >= {min}, got {val}")
        if max is not None and val > max:
            raise self.error(k, f"must be <= {max}, got {val}")
        return val

    def int(self, k: str, default: Any = ..., *, min: int | None = None) -> int:
        val = self.raw(k, default)
        if isinstance(val, bool) or not isinstance(val, int):
            raise self.error(k, f"must be an integer, got {val!r}")
        if min is not None and val < min:
            raise self.error(k, f"must be >= {min}, got {val}")
        return val

    def bool(self, k: str, default: Any = ...) -> bool:
        val = self.raw(k, default)
        if not isinstance(val, bool):
            raise self.error(k, f"must be true or false, got {val!r}")
        return val

    def vector(self, k: str, default: Any = ..., *, length: int | None = None,
               nonnegative: bool = False) -> np.ndarray:
        val = self.raw(k, default)
        try:
            arr = np.array(val, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise self.error(k, f"must be a list of numbers, got {val!r}") from None
        if length is not None and arr.size != length:
            raise self.error(k, f"must have {length} values, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise self.error(k, "values must be finite")
        if nonnegative and np.any(arr < 0):
            raise self.error(k, f"values must be >= 0, got {arr.tolist()}")
        return arr

    def list(self, k: str, default: Any = ...) -> list:
        val = self.raw(k, default)
        if val is None:
            return []
        if not isinstance(val, list):
            raise self.error(k, f"must be a list, got {type(val).__name__}")
        return val

    def finish(self) -> None:
        extra = [k for k in self.data if k not in self._used]
        if extra:
            allowed = ", ".join(sorted(self._used)) or "(none)"
            raise self.error(extra[0], f"unknown key; allowed here: {allowed}")

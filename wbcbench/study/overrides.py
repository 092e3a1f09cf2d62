"""Key-path overrides of a parsed YAML mapping: `params.step_length`, `pushes[0].force`, `tasks.com_xy.kp` (a list
of mappings with `name:` is indexed by name). Intermediate keys must exist; the leaf may be new, the loader then
validates it as in a file."""

from __future__ import annotations

import copy
import re

from ..errors import ConfigError

_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def split_path(path: str) -> list[str | int]:
    out: list[str | int] = []
    for name, index in _TOKEN.findall(path):
        out.append(int(index) if index else name)
    return out


def _step(node, tok, full: str, file: str):
    if isinstance(node, dict):
        if tok not in node:
            raise ConfigError(f"unknown key path '{full}' (no '{tok}'; has: {', '.join(map(str, node)) or 'nothing'})",
                              file=file, key=full)
        return node[tok]
    if isinstance(node, list):
        if isinstance(tok, str) and tok.isdigit():
            tok = int(tok)
        if isinstance(tok, int):
            if not 0 <= tok < len(node):
                raise ConfigError(f"unknown key path '{full}' (index {tok} of {len(node)} entries)", file=file,
                                  key=full)
            return node[tok]
        for item in node:
            if isinstance(item, dict) and item.get("name") == tok:
                return item
        names = [str(i.get("name")) for i in node if isinstance(i, dict) and "name" in i]
        raise ConfigError(f"unknown key path '{full}' (no entry named '{tok}'; have: {', '.join(names)})",
                          file=file, key=full)
    raise ConfigError(f"unknown key path '{full}' ('{tok}' under a value, not a mapping)", file=file, key=full)


def apply_overrides(data: dict, overrides: dict, file: str) -> dict:
    """A deep copy of `data` with every `path: value` of `overrides` set."""
    out = copy.deepcopy(data)
    for path, value in overrides.items():
        toks = split_path(path)
        if not toks:
            raise ConfigError("empty key path", file=file, key=path)
        node = out
        for tok in toks[:-1]:
            node = _step(node, tok, path, file)
        leaf = toks[-1]
        if isinstance(node, dict):
            node[leaf] = copy.deepcopy(value)
        elif isinstance(node, list):
            _step(node, leaf, path, file)
            node[int(leaf)] = copy.deepcopy(value)
        else:
            raise ConfigError(f"unknown key path '{path}' (parent is not a mapping)", file=file, key=path)
    return out

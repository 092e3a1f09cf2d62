"""A griffe extension for the API reference (mkdocs.yml, mkdocstrings `extensions:`).

wbcbench's docstrings are plain text that writes units in brackets (`(3,) [m] [rad, rad/s]`); Markdown would read
`[a] [b]` as a reference link. Brackets are escaped so that the docstrings show as written.
"""

from __future__ import annotations

import re

import griffe

_BRACKET = re.compile(r"(?<!\\)([\[\]])")


class PlainDocstrings(griffe.Extension):
    def on_instance(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _BRACKET.sub(r"\\\1", obj.docstring.value)

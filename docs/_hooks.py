"""MkDocs hooks of the documentation site (mkdocs.yml `hooks:`), so that a page only has to be written to be found.

- A Markdown page under docs/ that the nav does not list joins the nav section of its folder (docs/results/ ->
  Results, docs/tutorials/ -> Tutorials, ...; docs/*.md -> More), after the pages listed there.
- `<!-- wbcbench-help: COMMAND -->` in a page becomes that command's `wbcbench COMMAND --help`, taken from the
  parser itself, so the how-to pages cannot drift from the command line.
- A CLI command that no page shows with such a marker gets a generated how-to page, cli/COMMAND.md.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

MARKER = re.compile(r"<!--\s*wbcbench-help:\s*([\w-]+)\s*-->")
SECTIONS = {"concepts": "Concepts", "tutorials": "Tutorials", "cli": "How-to (CLI)", "api": "API reference",
            "results": "Results", "": "More"}
_generated: dict[str, str] = {}  # src_uri -> Markdown of the generated CLI pages
_helps: dict[str, str] = {}


def _command_helps(root: Path) -> dict[str, str]:
    """Each subcommand's --help, formatted at a fixed width so the site does not depend on the terminal."""
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    os.environ["COLUMNS"] = "110"
    from wbcbench.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return {name: p.format_help() for name, p in sub.choices.items()}


def _listed(nav) -> set[str]:
    out: set[str] = set()
    for item in nav or []:
        if isinstance(item, str):
            out.add(item)
        elif isinstance(item, dict):
            for v in item.values():
                out |= _listed(v) if isinstance(v, list) else {v}
    return out


def _section(nav: list, title: str) -> list:
    for item in nav:
        if isinstance(item, dict) and title in item and isinstance(item[title], list):
            return item[title]
    nav.append({title: []})
    return nav[-1][title]


def on_config(config):
    docs = Path(config["docs_dir"])
    _helps.clear()
    _helps.update(_command_helps(Path(config["config_file_path"]).parent))
    shown = {m for p in (docs / "cli").glob("*.md") for m in MARKER.findall(p.read_text())}
    _generated.clear()
    for name, text in _helps.items():
        if name not in shown:
            _generated[f"cli/{name}.md"] = (f"# wbcbench {name}\n\nThis page is made from the command's own help "
                                            f"(no how-to has been written for it yet).\n\n"
                                            f"<!-- wbcbench-help: {name} -->\n")
    nav = config["nav"]
    listed = _listed(nav)
    pages = sorted(p.relative_to(docs).as_posix() for p in docs.rglob("*.md"))
    for page in [*pages, *sorted(_generated)]:
        if page in listed:
            continue
        folder = page.split("/")[0] if "/" in page else ""
        _section(nav, SECTIONS.get(folder, folder.capitalize())).append(page)
    return config


def on_files(files, config):
    from mkdocs.structure.files import File

    for uri, content in _generated.items():
        if files.get_file_from_path(uri) is None:
            files.append(File.generated(config, uri, content=content))
    return files


def on_page_markdown(markdown, page, config, files):
    def help_block(m: re.Match) -> str:
        name = m.group(1)
        if name not in _helps:
            raise ValueError(f"{page.file.src_uri}: no CLI command '{name}' (commands: {', '.join(_helps)})")
        return f"```text\n$ wbcbench {name} --help\n{_helps[name].rstrip()}\n```"

    return MARKER.sub(help_block, markdown)

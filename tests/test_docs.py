"""The documentation: the README stays a front page, every section it used to hold has a page on the site, the
site builds with `mkdocs build --strict` (no broken link, no missing reference), and the tutorials' code runs.

Runnable blocks are marked in the Markdown, on the line before the fence:
    <!-- run -->              a ```python block (run in one namespace per page, in page order) or a ```bash block
                              (each `wbcbench ...` line run as `python -m wbcbench.cli ...`, which must exit 0)
    <!-- run: file NAME -->   the block's text is written to NAME (a YAML file the next blocks use)
    <!-- not run: REASON -->  a tutorial block that does not run here, and why (every tutorial block has one of these)
Each page runs in a temporary directory of its own (with `examples/` linked in), in a fresh Python process."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FORMER_HEADINGS = Path(__file__).with_name("former_readme_headings.txt")
HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*$", re.M)
BLOCK = re.compile(r"^<!--\s*run(?::\s*file\s+(?P<file>\S+))?\s*-->\s*\n```(?P<lang>\w+)[^\n]*\n(?P<code>.*?)^```",
                   re.M | re.S)


def _pages() -> list[Path]:
    return sorted(DOCS.rglob("*.md"))


def _headings(text: str) -> set[str]:
    """Headings outside fenced code blocks."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    return {h.strip() for h in HEADING.findall(text)}


def test_readme_is_a_front_page():
    """What a reader sees unfolded stays short: lines inside a collapsed <details> block (a per-item table the
    front page owes, folded) are not counted."""
    text = (ROOT / "README.md").read_text()
    folded = re.sub(r"<details>.*?</details>", "", text, flags=re.S)
    lines = folded.splitlines()
    assert len(lines) < 250, f"README.md has {len(lines)} lines outside <details>; results and narratives go to docs/"
    assert text.count("<details>") == text.count("</details>")


def test_every_former_readme_section_has_a_home_in_docs():
    """Each heading the README had before it became a front page (tests/former_readme_headings.txt, taken from
    it) is a heading of a page under docs/: the section moved, it was not dropped."""
    former = [re.sub(r"^#+\s*", "", h).strip() for h in FORMER_HEADINGS.read_text().splitlines() if h.strip()]
    assert len(former) == 19  # the file is the record of what the README held
    homes: dict[str, list[str]] = {}
    for page in _pages():
        for h in _headings(page.read_text()):
            homes.setdefault(h, []).append(str(page.relative_to(ROOT)))
    missing = [h for h in former if h not in homes]
    assert not missing, f"former README sections with no page under docs/: {missing}"


def test_readme_links_point_at_pages_that_exist():
    text = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+)", text)
    local = [t for t in targets if not t.startswith(("http://", "https://"))]
    assert local, "the README links into the documentation"
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, missing


def _load_hooks():
    spec = importlib.util.spec_from_file_location("wbcbench_docs_hooks", DOCS / "_hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_unlisted_pages_join_their_section_and_every_command_has_a_page(tmp_path):
    """The nav is easy to extend: a page the nav does not list joins its folder's section, and a CLI command that
    no how-to page shows gets a page made from its --help."""
    hooks = _load_hooks()
    docs = tmp_path / "docs"
    (docs / "results").mkdir(parents=True)
    (docs / "cli").mkdir()
    for page in ("index.md", "results/paper.md", "results/new-study.md", "cli/run.md", "extra.md"):
        (docs / page).write_text("# page\n")
    (docs / "cli/run.md").write_text("# run\n<!-- wbcbench-help: run -->\n")
    nav = [{"Home": "index.md"}, {"Results": [{"Paper": "results/paper.md"}]}, {"How-to (CLI)": ["cli/run.md"]}]
    config = {"docs_dir": str(docs), "config_file_path": str(ROOT / "mkdocs.yml"), "nav": nav}
    hooks.on_config(config)
    assert config["nav"][1]["Results"][-1] == "results/new-study.md"
    cli = config["nav"][2]["How-to (CLI)"]
    assert "cli/list.md" in cli and "cli/run.md" in cli and cli.count("cli/run.md") == 1
    assert {"More": ["extra.md"]} in config["nav"]
    assert "<!-- wbcbench-help: list -->" in hooks._generated["cli/list.md"]

    class Page:
        class file:
            src_uri = "cli/run.md"

    out = hooks.on_page_markdown("x\n<!-- wbcbench-help: run -->\n", Page, config, None)
    assert "$ wbcbench run --help" in out and "--controller" in out
    with pytest.raises(ValueError, match="no CLI command 'nope'"):
        hooks.on_page_markdown("<!-- wbcbench-help: nope -->", Page, config, None)


def test_site_builds_strict(tmp_path):
    """`mkdocs build --strict`, as `make docs` runs it: a broken link, a missing page or API reference fails."""
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None:
        pytest.skip("mkdocs / mkdocstrings not installed: pip install -e '.[docs]' (the Makefile's environment has it)")
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True, env={**__import__("os").environ,
                                                                        "NO_MKDOCS_2_WARNING": "1"})
    assert out.returncode == 0, out.stderr[-4000:]
    assert (tmp_path / "site/tutorials/your-controller/index.html").is_file()
    api = (tmp_path / "site/api/controllers/index.html").read_text()
    assert "Controller" in api and "reset" in api
    run_page = (tmp_path / "site/cli/run/index.html").read_text()
    assert "--controller" in run_page


def _runnable(page: Path) -> list[tuple[str, str | None, str]]:
    """(language, file name or None, code) of each marked block of a page, in order."""
    return [(m["lang"], m["file"], m["code"]) for m in BLOCK.finditer(page.read_text())]


PAGES_WITH_CODE = [p for p in _pages() if _runnable(p)]


def test_the_tutorials_have_runnable_code():
    names = {p.relative_to(DOCS).as_posix() for p in PAGES_WITH_CODE}
    for page in ("tutorials/your-controller.md", "tutorials/your-scenario.md", "tutorials/your-robot.md",
                 "tutorials/studies.md", "tutorials/teleoperation.md", "tutorials/watching.md"):
        assert page in names, f"{page} has no block marked <!-- run -->"


def test_every_tutorial_block_is_run_or_says_why_not():
    """A tutorial's code either runs in the tests or is marked `<!-- not run: REASON -->` (a fragment, a
    long or interactive command, one that another test already runs): no block is left out silently."""
    unmarked = []
    for page in sorted((DOCS / "tutorials").glob("*.md")):
        lines = page.read_text().splitlines()
        inside = False
        for i, line in enumerate(lines):
            if line.startswith("```"):
                if not inside and not re.match(r"<!--\s*(run\b|not run:\s*\S)", lines[i - 1] if i else ""):
                    unmarked.append(f"{page.name}:{i + 1}")
                inside = not inside
    assert not unmarked, f"code blocks marked neither <!-- run --> nor <!-- not run: REASON -->: {unmarked}"


DRIVER = textwrap.dedent('''
    import json, shlex, subprocess, sys
    blocks = json.load(open(sys.argv[1]))
    ns = {"__name__": "__main__"}
    for i, (lang, file, code) in enumerate(blocks):
        if file is not None:
            open(file, "w").write(code)
        elif lang == "python":
            exec(compile(code, f"<block {i}>", "exec"), ns)
        elif lang in ("bash", "sh", "console"):
            for line in code.splitlines():
                line = line.split(" #")[0].strip()
                if not line:
                    continue
                argv = shlex.split(line)
                if argv[0].endswith("wbcbench"):
                    argv = [sys.executable, "-m", "wbcbench.cli", *argv[1:]]
                print("$", line, flush=True)
                subprocess.run(argv, check=True)
        else:
            raise SystemExit(f"block {i}: cannot run a ```{lang} block")
''')


@pytest.mark.parametrize("page", PAGES_WITH_CODE, ids=lambda p: p.relative_to(DOCS).as_posix())
def test_page_code_runs(page, tmp_path):
    """The page's marked blocks run as a reader would run them, in order, from an empty directory."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    (tmp_path / "blocks.json").write_text(json.dumps(_runnable(page)))
    (tmp_path / "driver.py").write_text(DRIVER)
    env = {**__import__("os").environ}
    env["PYTHONPATH"] = str(ROOT) + (":" + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    out = subprocess.run([sys.executable, "driver.py", "blocks.json"], cwd=tmp_path, capture_output=True,
                         text=True, env=env, timeout=600)
    assert out.returncode == 0, f"{page.name}:\n{out.stdout[-3000:]}\n{out.stderr[-5000:]}"

"""The documentation site (mkdocs.yml, docs/): it builds with ``mkdocs build --strict`` (every
link, anchor and API reference checked); the command-line reference, a page per command, is
generated from the argparse definitions and names every option of every command and none that
does not exist; each ``COMMAND --help`` ends with the pointer to its page; every import path, module and
file the pages and the README show exists."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from csm_assets.cli import build_parser
from csm_assets.cli.common import DOCS_PAGE, docs_pointer

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CLI_PAGES = ROOT / DOCS_PAGE
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z-]*|-[a-zA-Z])\b")


def _hook():
    spec = importlib.util.spec_from_file_location("cli_reference", DOCS / "hooks" / "cli_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


HOOK = _hook()
COMMANDS = HOOK.commands()


def pages() -> dict[str, str]:
    """README.md and every Markdown page under docs/, by path relative to the repository."""
    found = {"README.md": (ROOT / "README.md").read_text(encoding="utf-8")}
    for path in sorted(DOCS.rglob("*.md")):
        found[str(path.relative_to(ROOT))] = path.read_text(encoding="utf-8")
    return found


def help_options(parser: argparse.ArgumentParser) -> set[str]:
    """The options the command declares and ``--help`` lists, without -h/--help."""
    found = {s for a in parser._actions if a.help != argparse.SUPPRESS for s in a.option_strings}
    usage = " ".join(parser.format_help().split())
    assert all(re.search(rf"(?<![\w-]){re.escape(s)}(?![\w-])", usage) for s in found)
    return found - {"-h", "--help"}


@pytest.mark.docs
def test_site_builds_strict(tmp_path):
    """`mkdocs build --strict` (the command the README gives): any warning (a broken link or
    anchor, a page missing from the nav, an API object mkdocstrings cannot find) fails it."""
    for module in ("mkdocs", "material", "mkdocstrings_handlers.python"):
        if importlib.util.find_spec(module.split(".")[0]) is None:
            pytest.skip(f"{module} is not installed (pip install -e '.[docs]')")
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                        "-d", str(site)], cwd=ROOT, capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, NO_MKDOCS_2_WARNING="1"))
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    for name in COMMANDS:  # the generated reference reached the command's page, one section per command
        html = (site / "reference" / "cli" / name.split()[0] / "index.html").read_text(encoding="utf-8")
        assert f'id="{name.replace(" ", "-")}"' in html and "csm-cli" not in html, name
    html = (site / "reference" / "cli" / "convert" / "index.html").read_text(encoding="utf-8")
    assert "--max-error" in html and "usage: csm-assets convert" in html


def cli_page(name: str) -> str:
    """The command's page of the reference (``bench cones`` is on ``bench.md``)."""
    return (CLI_PAGES / f"{name.split()[0]}.md").read_text(encoding="utf-8")


def test_cli_reference_has_a_page_per_command_and_an_index():
    tops = {name for name in COMMANDS if " " not in name}
    pages = {p.stem for p in CLI_PAGES.glob("*.md")}
    assert pages == tops | {"index"}, "one page per top-level command, plus index.md"
    index = (CLI_PAGES / "index.md").read_text(encoding="utf-8")
    assert all(f"]({name}.md)" in index for name in tops), "the index links every command's page"
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert all(f"reference/cli/{name}.md" in nav for name in tops | {"index"})


def test_cli_pages_have_a_section_and_marker_per_command():
    markers = [m for p in CLI_PAGES.glob("*.md") for m in HOOK.MARKER.findall(p.read_text(encoding="utf-8"))]
    assert sorted(markers) == sorted(COMMANDS), "one <!-- csm-cli NAME --> marker per command"
    for name in COMMANDS:
        anchor = name.replace(" ", "-")
        text = cli_page(name)
        assert HOOK.MARKER.search(text) and f"<!-- csm-cli {name} -->" in text, f"{name}: marker on another page"
        assert re.search(rf"^#+ .*\{{#{anchor}\}}\s*$", text, re.M), f"no heading with id {anchor}"


@pytest.mark.parametrize("name", list(COMMANDS))
def test_generated_reference_lists_exactly_the_options_of_help(name):
    """The generated section of each command names every option its --help lists and no other."""
    parser = COMMANDS[name]
    generated = HOOK.reference(name, parser)
    body = generated.split("```", 2)[2]  # the tables, after the usage block
    assert set(OPTION.findall(body)) == help_options(parser)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):  # a row per subcommand
            assert all(f"| `{sub}` |" in body for sub in action.choices), name
        elif not action.option_strings and action.help != argparse.SUPPRESS:
            assert f"`{action.metavar or action.dest}`" in body, f"{name}: positional {action.dest}"


def _sections(text: str) -> dict[str, str]:
    """A command page's hand-written text per command (between a heading and the next)."""
    found = {}
    parts = re.split(r"^(#{1,3} .*\{#([a-z-]+)\})\s*$", text, flags=re.M)
    for i in range(1, len(parts), 3):
        found[parts[i + 1]] = parts[i + 2]
    return found


def test_cli_page_prose_names_only_real_options():
    """Every `--option` the hand-written text of a command's section names is one it takes."""
    for name, parser in COMMANDS.items():
        sections = _sections(cli_page(name))
        prose = re.sub(r"```.*?```", "", HOOK.MARKER.sub("", sections[name.replace(" ", "-")]), flags=re.S)
        named = {o for code in re.findall(r"`([^`]+)`", prose) for o in OPTION.findall(code)
                 if not code.startswith("csm-assets ")}
        assert named - help_options(parser) - {"-h", "--help"} == set(), name


def _command_lines():
    """(page, command, options) of every ``csm-assets COMMAND ...`` line the pages show, in code
    blocks and inline code (comments after `` # `` left out)."""
    for page, text in pages().items():
        code = re.findall(r"```(?:sh|bash|console|text)?\n(.*?)```", text, re.S)
        lines = [ln for block in code for ln in block.splitlines()] + re.findall(r"`(csm-assets [^`]+)`", text)
        for line in lines:
            for part in re.split(r"&&|\|\||;", line.split(" # ")[0]):
                m = re.search(r"csm-assets ((?:(?:bench|blender|config) )?[a-z]+)\b(.*)", part)
                if m and m.group(1) in COMMANDS:
                    yield page, m.group(1), set(OPTION.findall(re.sub(r"\S*[/.]\S*", "", m.group(2))))


def test_command_lines_in_the_docs_name_only_real_options():
    bad = [(page, name, sorted(opts - help_options(COMMANDS[name]) - {"-h", "--help"}))
           for page, name, opts in _command_lines()
           if opts - help_options(COMMANDS[name]) - {"-h", "--help"}]
    assert bad == [], "command lines naming options the command does not take"


@pytest.mark.parametrize("name", list(COMMANDS))
def test_help_ends_with_its_docs_pointer(name):
    pointer = docs_pointer(f"csm-assets {name}")
    words = name.split()
    assert pointer == f"docs: {DOCS_PAGE}/{words[0]}.md" + (f"#{'-'.join(words)}" if len(words) > 1 else "")
    assert (ROOT / pointer.removeprefix("docs: ").split("#")[0]).is_file()
    assert COMMANDS[name].format_help().rstrip().endswith(pointer)


def test_help_pointer_from_the_installed_command():
    r = subprocess.run([sys.executable, "-m", "csm_assets", "convert", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.rstrip().splitlines()[-1] == "docs: docs/reference/cli/convert.md"
    r = subprocess.run([sys.executable, "-m", "csm_assets", "--help"], capture_output=True, text=True)
    assert r.stdout.rstrip().splitlines()[-1] == "docs: docs/reference/cli/index.md", r.stdout


def test_version():
    import csm_assets

    r = subprocess.run([sys.executable, "-m", "csm_assets", "--version"], capture_output=True, text=True)
    assert (r.returncode, r.stdout.strip()) == (0, f"csm-assets {csm_assets.__version__}")
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert f'version = "{csm_assets.__version__}"' in pyproject


def _resolve(dotted: str):
    """Import the longest module prefix of ``dotted`` and get the rest as attributes."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(dotted)


def test_every_import_path_the_docs_show_works():
    """``from csm_assets.x import a, b``, ``import csm_assets.x``, dotted names ``csm_assets.x.y``
    and, after ``import csm_assets as csm``, ``csm.name``: each one resolves."""
    missing = []
    for page, text in pages().items():
        names = set()
        imports = re.findall(r"from (csm_assets[\w.]*) import \(([\w,\s]+)\)", text)
        imports += re.findall(r"from (csm_assets[\w.]*) import ([\w, ]+)", text)
        for module, items in imports:
            names |= {f"{module}.{n.strip()}" for n in items.split(",") if n.strip()}
        names |= set(re.findall(r"import (csm_assets[\w.]*)", text))
        names |= {n.rstrip(".") for n in re.findall(r"(?<![\w/])csm_assets(?:\.\w+)+", text)}
        if "import csm_assets as csm" in text:
            names |= {"csm_assets" + n for n in re.findall(r"(?<![\w.])csm(\.\w+)+", text)}
        for name in sorted(names):
            try:
                _resolve(name)
            except (ImportError, AttributeError) as e:
                missing.append(f"{page}: {name} ({e})")
    assert missing == []


def test_every_file_path_the_docs_show_exists():
    """Paths into the repository (`csm_assets/...`, `tests/...`, `benchmarks/...`, `shaders/...`,
    `samples/...`, `docs/...`, `.ci/...`) name files or folders that exist."""
    missing = []
    for page, text in pages().items():
        for path in set(re.findall(r"(?<![\w./-])((?:csm_assets|tests|benchmarks|shaders|samples|docs|\.ci)"
                                   r"/[\w./*-]*[\w*])", text)):
            if not any(ROOT.glob(path)):  # a pattern (tests/test_attack_*.py) names at least one
                missing.append(f"{page}: {path}")
    assert missing == []


def test_usd_validation_script_the_docs_show(tmp_path):
    """docs/guides/validate.md's `python tests/tools/usd_validate.py STAGE` on a converted sample:
    no errors, exit 0 (and the error it reports without the CSM shader's registration is real)."""
    from csm_assets.convert.pipeline import convert

    convert(ROOT / "samples" / "brick_wall.usda", tmp_path / "out")
    stage = tmp_path / "out" / "brick_wall.usda"
    script = ROOT / "tests" / "tools" / "usd_validate.py"
    r = subprocess.run([sys.executable, str(script), str(stage)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip().endswith("0 error(s)"), r.stdout + r.stderr
    unregistered = tmp_path / "unregistered.py"
    unregistered.write_text(script.read_text().replace("\nregister_shader_definitions()", "\n"))
    r = subprocess.run([sys.executable, str(unregistered), str(stage)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 1 and "MissingShaderIdInRegistry" in r.stdout, r.stdout + r.stderr


QUICK_START = [
    "python3 -m venv .venv && .venv/bin/pip install -q . && .venv/bin/csm-assets stepmap samples/cobbles.png "
    "-o cobbles_stepmap.png && .venv/bin/csm-assets convert samples/brick_wall.gltf -o converted",
    "python3 -m venv .venv && .venv/bin/pip install -q tox && .venv/bin/tox -q",
]


def test_readme_is_short_and_keeps_the_quick_start():
    """README.md under 15 KB, with the two quick-start lines as they are: `.ci/run` runs the second
    line of the sh block under `## Quick start` (CI's test command)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) < 15 * 1024
    block = text.split("## Quick start", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    assert block.splitlines() == QUICK_START
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "sed -n 2p" in ci and "## Quick start" in ci


def test_readme_links_into_the_docs_and_shows_one_picture():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\((docs/[^)#]+)(?:#[^)]*)?\)", text)
    assert links and all((ROOT / link).is_file() for link in links), links
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(pictures) == 1 and (ROOT / pictures[0]).is_file()
    assert "mkdocs build --strict" in text

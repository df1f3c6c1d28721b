"""Attacks on the project configuration: any TOML of the wrong shape, files that are no
regular file (FIFOs, devices, dangling links, huge files), discovery fooled by text, and
globs of exponential cost. Each is exit 2 with one line naming the file (and line), never an
internal error, a hang or a walk of minutes; the hangs run in a subprocess with a timeout
far above the bound."""

from __future__ import annotations

import datetime
import json
import math
import os
import textwrap
from pathlib import Path

import pytest
from attack import assert_clean_error, run_cli, run_cli_here
from conftest import OBJ_WALL, copy_samples, examples
from hypothesis import given, strategies as st

from csm_assets.cli.scenes import check_value
from csm_assets.config.files import MAX_BYTES, ConfigError, find_config
from csm_assets.config.load import load, option_fields
from csm_assets.config.settings import Resolver
from csm_assets.errors import OptionError

HANG = 120  # seconds: every refusal here takes well under 5 (interpreter start included)


def _project(root: Path) -> Path:
    copy_samples(root / "models", OBJ_WALL)
    copy_samples(root / "textures", ["bricks_height.png"])
    (root / ".git").mkdir()
    return root


@pytest.fixture
def project(tmp_path) -> Path:
    return _project(tmp_path / "project")


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


def refused(cfg: Path, line: int | None, words: str) -> None:
    with pytest.raises(ConfigError) as e:
        load(cfg, check_value)
    where = f"{cfg.resolve()}:{line}: " if line else f"{cfg.resolve()}: "
    assert str(e.value).startswith(where) and words in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert len(str(e.value)) < len(where) + 1100, len(str(e.value))


# ---- shapes that parse but are wrong ---------------------------------------------------------

DEEP = "[" * 500 + "]" * 500
SHAPES = [
    (f"x = {DEEP}\n", 1, "nested more than 64 deep"),
    (f'bits = 8\n[scenes."models/*.obj"]\nsteps = {DEEP}\n', 3, "nested more than 64 deep"),
    ("depth = { a = " + "{ b = " * 300 + "1" + " }" * 301 + "\n", 1, "nested more than 64 deep"),
    ("\ndepth." + "a." * 3000 + "b = 1\n", 2, "nested more than 64 deep"),  # deep without brackets
    ("\n\n[" + "a." * 3000 + "b]\nx = 1\n", 3, "nested more than 64 deep"),
    ("steps = 1" + "0" * 5000 + "\n", 1, "thousands of digits"),
    ("steps = 1" + "0" * 4200 + "\n", 1, "64-bit range"),
    ("bits = 8\nsteps = 9223372036854775808\n", 2, "64-bit range"),
    ("error-on = [1, 2]\n", 1, "expected a list of text"),
    ("ignore = [[\"CSM205\"]]\n", 1, "expected a list of text"),
    ("bits = 1979-05-27\n", 1, "expected a whole number, got date"),
    ("max-ratio = 07:32:00\n", 1, "expected a number, got time"),
    ("variant = { a = 1 }\n", 1, "expected text, got a table"),
    ("tile = [true]\n", 1, "expected true or false, got a list"),
    ("height = \"textures/bricks_height.png\"\n", 1, "expected a table of material"),
    ("height = { bricks = [\"x\"] }\n", 1, "expected a path (text), got a list"),
    ("height = { bricks = \"textures\" }\n", 1, "not a regular file 'textures'"),
    ("height = { bricks = \"" + "a" * 5000 + "\" }\n", 1, "cannot read"),
    ("height = { bricks = \"a\\u0000b\" }\n", 1, "NUL"),
    ("depth = { bricks = { x = 1 } }\n", 1, "depth must be a number"),
    ("depth = [0.1]\n", 1, "depth must be a number"),
    ("depth = [" + "1.5, " * 100000 + "]\n", 1, "depth must be a number, got [1.5, 1.5"),  # shown cut short
    ("scenes = []\n", 1, "scenes: expected a table, got a list"),
    ("[[scenes]]\nbits = 8\n", 1, "scenes: expected a table, got a list"),
    ("[scenes]\n\"models/*.obj\" = 8\n", 2, "expected a table, got a whole number"),
    ("[scenes]\n\"models/*.obj\" = [{ bits = 8 }]\n", 2, "expected a table, got a list"),
    ("[scenes.\"\"]\nbits = 8\n", 1, "a glob relative to this file's folder"),
    ("[scenes.\"./\"]\nbits = 8\n", 1, "a glob relative to this file's folder"),
    ("[scenes.\"a\\u0000b\"]\nbits = 8\n", 1, "a glob relative to this file's folder"),
    ("[scenes.\"models/**\"]\nbits = 8\n", 1, "matches folders only"),
    ("[scenes.\"models/*.obj\"]\nscenes = {}\n", 2, "unknown key"),
    ("tool = \"x\"\n", 1, "unknown key"),  # in csm-assets.toml, tool is no key
]


@pytest.mark.parametrize("text, line, words", SHAPES, ids=[f"{i}-{s[2][:24]}" for i, s in enumerate(SHAPES)])
def test_any_shape_is_a_config_error_with_its_line(project, text, line, words):
    cfg = project / "csm-assets.toml"
    cfg.write_text(text)
    refused(cfg, line, words)


PYPROJECTS = [
    ("title = 1\ntool = \"x\"\n[project]\nname = \"x\"\n", 2, "tool: expected a table, got text"),
    ("[tool]\ncsm-assets = 3\n", 2, "tool.csm-assets: expected a table, got a whole number"),
    ("[[tool.csm-assets]]\nbits = 8\n", 1, "tool.csm-assets: expected a table, got a list"),
    ("[tool.csm-assets]\nscenes = 1\n", 2, "scenes: expected a table"),
    ("[tool.csm-assets]\ndepth = { a = \"x\" }\n", 2, "depth.a"),
    ("[project]\nname = \"x\"\n", None, "has no [tool.csm-assets] table"),
]


@pytest.mark.parametrize("text, line, words", PYPROJECTS, ids=[p[2][:24] for p in PYPROJECTS])
def test_a_pyproject_of_the_wrong_shape_is_exit_2_naming_it(project, text, line, words):
    """``--config pyproject.toml`` with a ``tool`` that is no table (an AttributeError, exit 3
    before), or no ``[tool.csm-assets]`` at all."""
    cfg = project / "pyproject.toml"
    cfg.write_text(text)
    refused(cfg, line, words)
    r = run_cli_here("config", "show", project / "models" / "brick_wall.obj", "--config", cfg)
    assert f"{cfg.resolve()}{f':{line}' if line else ''}: " in assert_clean_error(r, 2, cfg)


def test_numbers_too_big_for_a_float_are_refused_on_the_command_line_too(project):
    r = run_cli_here("config", "show", project / "models" / "brick_wall.obj", "--steps", "1" + "0" * 4200)
    assert "--steps" in assert_clean_error(r, 2)


# ---- random shapes: never an internal error --------------------------------------------------

KEYS = sorted([*option_fields(), "height", "depth-map", "depth", "scenes", "tool", "x"])
_SCALARS = (st.booleans() | st.integers(-(1 << 70), 1 << 70) | st.sampled_from([0, 1, 8, 16, -1, (1 << 63) - 1])
            | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12)
            | st.sampled_from(["textures/bricks_height.png", "textures", "CSM205", "exact", "models/*.obj"])
            | st.dates() | st.times())
_NAMES = st.sampled_from(["bricks", "a", "", "models/*.obj", "**/*.obj", "models/**", "../x", "/abs", "*"]) | \
    st.text(max_size=6)
_VALUES = st.recursive(_SCALARS, lambda inner: st.lists(inner, max_size=3)
                       | st.dictionaries(_NAMES | st.sampled_from(KEYS), inner, max_size=3), max_leaves=12)
_TABLES = st.dictionaries(st.sampled_from(KEYS) | _NAMES, _VALUES, max_size=5)


def _toml_string(s: str) -> str:
    out = json.dumps(s, ensure_ascii=False)  # TOML's basic strings escape as JSON does, and DEL
    return out.replace("\x7f", "\\u007f")


def _toml(value) -> str:
    """``value`` as one TOML value (inline tables and arrays)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, (int, datetime.date, datetime.time)):
        return str(value) if isinstance(value, int) else value.isoformat()
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return "{ " + ", ".join(f"{_toml_string(k)} = {_toml(v)}" for k, v in value.items()) + " }"


@pytest.fixture(scope="module")
def shared_project(tmp_path_factory) -> Path:
    return _project(tmp_path_factory.mktemp("shapes") / "project")


@examples(1.0)
@given(top=_TABLES, scenes=st.none() | st.dictionaries(_NAMES, _VALUES | _TABLES, max_size=3),
       pyproject=st.booleans())
def test_random_shapes_never_give_an_internal_error(shared_project, top, scenes, pyproject):
    """Any TOML that parses, as a csm-assets.toml or under a pyproject's [tool.csm-assets]:
    the settings, or a ConfigError naming the file (or an OptionError naming the scene), one line."""
    body = "".join(f"{_toml_string(k)} = {_toml(v)}\n" for k, v in top.items() if k != "scenes")
    if scenes is not None:
        body += f"scenes = {_toml(scenes)}\n"
    name = "pyproject.toml" if pyproject else "csm-assets.toml"
    for other in ("pyproject.toml", "csm-assets.toml"):
        (shared_project / other).unlink(missing_ok=True)
    cfg = shared_project / name
    cfg.write_text("[tool.csm-assets]\n" + body if pyproject else body, encoding="utf-8")
    scene = shared_project / "models" / "brick_wall.obj"
    try:
        assert find_config(scene) == cfg
        Resolver(config=None, check=check_value).options(scene)
    except ConfigError as e:
        assert str(e).startswith(f"{cfg.resolve()}") and "\n" not in str(e), str(e)
    except OptionError as e:  # settings that do not go together, naming where they came from
        assert (str(scene) in str(e) or str(cfg.resolve()) in str(e)) and "\n" not in str(e), str(e)


@examples(0.5)
@given(tool=_VALUES, before=st.text(max_size=20))
def test_random_pyproject_tools_never_give_an_internal_error(shared_project, tool, before):
    """Discovery parses each pyproject.toml on the walk: any ``tool`` value finds it or passes
    it over; a ``[tool.csm-assets]`` only in a string or a comment is no table."""
    for other in ("pyproject.toml", "csm-assets.toml"):
        (shared_project / other).unlink(missing_ok=True)
    cfg = shared_project / "pyproject.toml"
    cfg.write_text(f"title = {_toml_string(before + '[tool.csm-assets]')}\n# [tool.csm-assets]\ntool = {_toml(tool)}\n",
                   encoding="utf-8")
    found = isinstance(tool, dict) and "csm-assets" in tool
    scene = shared_project / "models" / "brick_wall.obj"
    if _within_toml(tool):
        assert find_config(scene) == (cfg if found else None)
    else:  # TOML's integers have 64 bits: the file is no TOML, whatever the table
        with pytest.raises(ConfigError, match=f"^{cfg}:3: .*64-bit range"):
            find_config(scene)


def _within_toml(value) -> bool:
    if isinstance(value, dict):
        return all(map(_within_toml, value.values()))
    if isinstance(value, list):
        return all(map(_within_toml, value))
    return not isinstance(value, int) or -(1 << 63) <= value < (1 << 63)


# ---- discovery by parsing -----------------------------------------------------------------------

def test_a_table_named_only_in_a_string_does_not_hide_the_root_configuration(project):
    root_cfg = write(project / "csm-assets.toml", "bits = 16\n")
    write(project / "models" / "pyproject.toml", '''
        [project]
        description = """
        [tool.csm-assets]
        """
        # [tool.csm-assets] is in a comment too
        ''')
    scene = project / "models" / "brick_wall.obj"
    assert find_config(scene) == root_cfg
    assert Resolver().settings(scene).settings["bits"].value == 16
    write(project / "models" / "pyproject.toml", "[tool]\ncsm-assets = { bits = 8 }\n")  # a table, no header
    assert find_config(scene) == project / "models" / "pyproject.toml"
    assert Resolver().options(scene).bits == 8


def test_a_broken_pyproject_on_the_walk_is_named(project):
    """As ruff does: a pyproject.toml that cannot be parsed may be the configuration meant."""
    cfg = write(project / "pyproject.toml", "[project\nname = 1\n")
    r = run_cli_here("config", "show", project / "models" / "brick_wall.obj")
    assert f"{cfg}:1: not valid TOML" in assert_clean_error(r, 2, cfg)


# ---- files that are no regular file: one line, exit 2, no hang --------------------------------

def _make(path: Path, kind: str) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    elif kind == "dangling":
        path.symlink_to("gone.toml")
    elif kind == "loop":
        path.symlink_to(path.name)
    elif kind == "folder":
        path.mkdir()
    elif kind == "huge":  # sparse: 8 GiB that no disk holds
        with open(path, "wb") as f:
            f.truncate(8 << 30)
    elif kind == "big":
        path.write_text("# " + "x" * MAX_BYTES + "\n")


KINDS = {"fifo": "is a FIFO", "dev-zero": "is a character device", "dangling": "a symbolic link to 'gone.toml', "
         "which does not exist", "loop": "cannot read", "folder": "is a folder", "huge": "larger than 1 MiB",
         "big": "larger than 1 MiB"}


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX")
@pytest.mark.parametrize("name", ["csm-assets.toml", "pyproject.toml"])
@pytest.mark.parametrize("kind", sorted(KINDS))
def test_a_configuration_that_is_no_regular_file_is_named(project, name, kind):
    """Found on the walk and named by --config alike, by convert, check, hook and config show:
    refused from its stat (a FIFO is never opened, /dev/zero never read, a huge file never
    read past the bound). What could hang or fill the memory runs in a subprocess with a
    timeout far above the refusal's time."""
    cfg = project / "models" / name
    _make(cfg, kind)
    scene = project / "models" / "brick_wall.obj"
    runs = [["config", "show", scene], ["check", scene, "--config", cfg], ["hook", scene],
            ["convert", scene, "-o", project / "out"]]
    hangs = kind in ("fifo", "dev-zero", "huge")
    for argv in runs[1:3] if hangs else runs:
        r = run_cli(*argv, timeout=HANG) if hangs else run_cli_here(*argv)
        line = assert_clean_error(r, 2, cfg)
        assert f"{cfg}: {KINDS[kind]}" in line, line
    assert not (project / "out").exists() and not (project / "models" / "brick_wall_obj_csm").exists()


# ---- globs: bounded cost, pathlib's matches ------------------------------------------------------

def test_many_double_stars_on_a_deep_tree_take_no_time(project):
    """Seven ``**`` on a tree 40 folders deep: pathlib walked it again per ``**`` (92 s on 20
    folders, about ten times more per ``**`` at 30); one walk now, in a subprocess with a timeout
    far above it."""
    deep = project / "models"
    for i in range(40):
        deep = deep / f"d{i}"
        deep.mkdir()
        (deep / "note.txt").write_text("")
    copy_samples(deep, OBJ_WALL)
    write(project / "csm-assets.toml", f"""
        [scenes."{'/'.join(['**'] * 7)}/*.obj"]
        bits = 16
        [scenes."models/{'/'.join(['**', '*'] * 30)}/**/brick_wall.obj"]
        steps = 9
        """)
    r = run_cli("config", "show", deep / "brick_wall.obj", "--json", timeout=HANG)
    assert r.returncode == 0, r.stderr
    shown = {row["key"]: row["value"] for row in json.loads(r.stdout)["settings"]}
    assert shown["bits"] == 16 and shown["steps"] == 9

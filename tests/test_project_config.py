"""The project configuration: discovery (as ruff and pre-commit find theirs), keys with their
lines, checks that name the file and line (exit 2), precedence (defaults < the table of every
scene < matching ``[scenes."GLOB"]`` tables < the command line) and ``config show``."""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

import pytest
from attack import run_cli
from conftest import GLTF_WALL, OBJ_WALL, SAMPLES, copy_samples
from hypothesis import given, strategies as st

from csm_assets.config.files import find_config, project_root
from csm_assets.config.load import ConfigError, load, option_fields
from csm_assets.config.settings import Resolver
from csm_assets.config.toml_lines import key_lines, line_of
from csm_assets.convert.options import ConvertOptions


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


@pytest.fixture
def project(tmp_path):
    """A project: models/ with the glTF and OBJ walls, textures/ beside it, no configuration yet."""
    root = tmp_path / "project"
    copy_samples(root / "models", [n for n in GLTF_WALL if n != "bricks_height.png"])
    copy_samples(root / "models", OBJ_WALL)
    copy_samples(root / "textures", ["bricks_height.png", "cobbles.png"])
    (root / ".git").mkdir()  # the repository's root, for discovery (no git needed)
    return root


# ---- discovery -------------------------------------------------------------------------------

def test_nearest_configuration_wins_and_the_walk_stops_at_the_repository(project, tmp_path):
    scene = project / "models" / "brick_wall.gltf"
    assert find_config(scene) is None and project_root(scene) == project.resolve()  # the repository's root
    write(tmp_path / "csm-assets.toml", "bits = 16\n")  # above the repository: never applies
    assert find_config(scene) is None
    write(project / "pyproject.toml", "[project]\nname = 'x'\n")  # no [tool.csm-assets]: not a configuration
    assert find_config(scene) is None
    write(project / "pyproject.toml", "[project]\nname = 'x'\n[tool.csm-assets]\nbits = 16\n")
    assert find_config(scene) == (project / "pyproject.toml").resolve()
    write(project / "models" / "csm-assets.toml", "bits = 8\n")  # nearer
    assert find_config(scene) == (project / "models" / "csm-assets.toml").resolve()
    assert project_root(scene) == (project / "models").resolve()
    write(project / "models" / "pyproject.toml", "[tool.csm-assets]\nbits = 16\n")  # csm-assets.toml first
    assert find_config(scene) == (project / "models" / "csm-assets.toml").resolve()


def test_without_repository_or_configuration_the_root_is_the_scenes_folder(tmp_path):
    scene = copy_samples(tmp_path / "a", GLTF_WALL) / "brick_wall.gltf"
    assert project_root(scene) == scene.parent.resolve()


def test_pyproject_table_is_read_with_its_lines(project):
    write(project / "pyproject.toml", """
        [project]
        name = "assets"

        [tool.csm-assets]
        bits = 16

        [tool.csm-assets.scenes."models/*.obj"]
        depth = 0.2
        """)
    cfg = load(project / "pyproject.toml")
    top, obj = cfg.sections
    assert [(v.key, v.value, v.where.rsplit(":", 1)[1]) for v in top.values] == [("bits", 16, "5")]
    assert [(v.key, v.value, v.where.rsplit(":", 1)[1]) for v in obj.values] == [("depth", 0.2, "8")]
    assert obj.matches == {(project / "models" / "brick_wall.obj").resolve()}


# ---- errors name the file and the line (exit 2) ----------------------------------------------

BAD = [
    ("bits = 16\nmax_error = 1\n", 2, "unknown key; did you mean 'max-error'?"),
    ("bits = 12\n", 1, "invalid choice: 12"),
    ("max-error = -1\n", 1, "max-error"),
    ("self-shadow = \"yes\"\n", 1, "expected true or false, got text"),
    ("steps = 2.5\n", 1, "expected a whole number, got a number"),
    ("height = { bricks = \"textures/bricks_height.png\" }\ndepth-map = { bricks = \"textures/cobbles.png\" }\n", 2,
     "two height textures"),
    ("depth = { bricks = 0 }\n", 1, "finite number > 0"),
    ("[scenes.\"../*.gltf\"]\nbits = 8\n", 1, "without '..'"),
    ("scenes = 3\n", 1, "expected a table"),
    ("bits = 8\nbits = 16\n", 2, "not valid TOML"),
    ("force = true\n", 1, "unknown key"),  # not a setting of the outputs: a command-line flag only
    ("bits = 8\nerror-on = [\"CSM999\"]\n", 2, "'CSM999' is not a warning code"),
    ("ignore = \"CSM205\"\n", 1, "expected a list of text, got text"),
    ("strict = 1\n", 1, "expected true or false"),
]


@pytest.mark.parametrize("text, line, words", BAD, ids=[b[2][:30] for b in BAD])
def test_a_configuration_that_cannot_be_used_names_file_and_line(project, text, line, words):
    from csm_assets.cli.scenes import check_value

    cfg = project / "csm-assets.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as e:
        load(cfg, check_value)
    assert str(e.value).startswith(f"{cfg.resolve()}:{line}: ") and words in str(e.value), str(e.value)


def test_a_glob_matching_nothing_is_a_warning_not_an_error(project):
    """A scene moved away leaves its entry matching nothing: it names no scene, so it fails none."""
    cfg = project / "csm-assets.toml"
    cfg.write_text("bits = 8\n\n[scenes.\"nothing/*.gltf\"]\nbits = 16\n")
    with pytest.warns(UserWarning, match=rf"{cfg.resolve()}:3: .*matches no scene file.*apply to nothing"):
        top, gone = load(cfg).sections
    assert gone.matches == frozenset() and top.values[0].value == 8


def test_a_missing_texture_fails_only_the_scenes_its_entry_names(project):
    from csm_assets.config.settings import Resolver

    cfg = project / "csm-assets.toml"
    cfg.write_text("\n\n[scenes.\"models/*.gltf\"]\nheight = { bricks = \"textures/missing.png\" }\n")
    top, entry = load(cfg).sections
    assert [str(p) for p in entry.problems] == [f"{cfg.resolve()}:4: scenes.\"models/*.gltf\".height.bricks: "
                                                "no such file 'textures/missing.png' (paths are relative to "
                                                "csm-assets.toml's folder)"]
    with pytest.raises(ConfigError, match="no such file"):
        Resolver().settings(project / "models" / "brick_wall.gltf")
    assert Resolver().settings(project / "models" / "brick_wall.obj")  # not named: fine


def test_config_errors_exit_2_on_every_command(project):
    write(project / "csm-assets.toml", "bits = 16\n\n[scenes.\"models/*.gltf\"]\nmax_error = 1\n")
    scene = project / "models" / "brick_wall.gltf"
    where = f"{(project / 'csm-assets.toml').resolve()}:4: "
    for argv in (["check", scene], ["hook", scene], ["convert", scene, "-o", project / "out"],
                 ["config", "show", scene]):
        r = run_cli(*argv)
        assert r.returncode == 2 and where in r.stderr and "Traceback" not in r.stderr, (argv, r)
    assert not (project / "out").exists() and not (project / "models" / "brick_wall_gltf_csm").exists()


def test_a_material_the_scene_does_not_have_names_the_line(project):
    write(project / "csm-assets.toml", """
        bits = 8

        [scenes."models/*.gltf"]
        height = { Bricks = "textures/bricks_height.png" }
        """)
    scene = project / "models" / "brick_wall.gltf"
    for argv in (["hook", scene], ["convert", scene, "-o", project / "out"], ["check", scene]):
        r = run_cli(*argv)
        assert r.returncode == 2, (argv, r)
        assert f"{(project / 'csm-assets.toml').resolve()}:4: names material 'Bricks'" in r.stderr
        assert "its materials: 'bricks'" in r.stderr
    assert not (project / "models" / "brick_wall_gltf_csm").exists()


# ---- precedence and `config show` --------------------------------------------------------------

def test_later_tables_then_the_command_line_win(project):
    write(project / "csm-assets.toml", """
        bits = 16
        depth = 0.3
        self-shadow = true

        [scenes."models/*"]
        depth = 0.2

        [scenes."models/brick_wall.obj"]
        depth-map = { bricks = "textures/cobbles.png" }
        depth = { bricks = 0.05 }
        max-error = 1.5
        """)
    obj, gltf = project / "models" / "brick_wall.obj", project / "models" / "brick_wall.gltf"
    cfg = (project / "csm-assets.toml").resolve()
    s = Resolver().settings(obj).settings
    assert (s["bits"].value, s["bits"].source) == (16, f"{cfg}:1")
    assert (s["depth"].value, s["depth"].source) == (0.2, f"{cfg}:6")
    assert s["variant"].value == "auto" and s["variant"].source == "default (with max-error)"
    assert s[("heights", "bricks")].value.depth_map and s[("heights", "bricks")].source == f"{cfg}:9"
    assert s[("depths", "bricks")].value == 0.05
    assert s["tile"].source == "default" and s["tile"].value is None
    opts = Resolver().options(gltf)
    assert (opts.bits, opts.depth, opts.heights, opts.max_error, opts.variant) == (16, 0.2, {}, None, "exact")
    assert opts.root == project.resolve()
    from csm_assets.cli.scenes import check_value
    from csm_assets.config.settings import COMMAND_LINE
    from csm_assets.config.load import Value

    given = [Value("bits", "bits", 8, COMMAND_LINE), Value("variant", "variant", "loop", COMMAND_LINE)]
    opts = Resolver(given, check=check_value).options(obj)
    assert (opts.bits, opts.variant, opts.max_error, opts.self_shadow) == (8, "loop", 1.5, True)
    assert opts.named_by == {"bricks": f"{cfg}:9"}


def test_config_show_prints_each_setting_and_where_it_comes_from(project, tmp_path):
    write(project / "csm-assets.toml", """
        bits = 16

        [scenes."models/*.obj"]
        height = { bricks = "textures/bricks_height.png" }
        """)
    r = run_cli("config", "show", "models/brick_wall.obj", "--max-ratio", "0.5", cwd=project)
    assert r.returncode == 0, r
    lines = {ln.split("=")[0].strip(): ln for ln in r.stdout.splitlines() if " = " in ln}
    cfg = (project / "csm-assets.toml").resolve()
    assert lines["bits"].endswith(f"# {cfg}:1") and " 16 " in lines["bits"]
    assert lines["max-ratio"].endswith("# command line") and "0.5" in lines["max-ratio"]
    assert lines["variant"].endswith("# default") and '"exact"' in lines["variant"]
    assert '"textures/bricks_height.png"' in lines["height.bricks"] and lines["height.bricks"].endswith(f":4")
    assert set(lines) == {*option_fields(), "height.bricks"}
    r = run_cli("config", "show", project / "models" / "brick_wall.obj", "--json", cwd=tmp_path)
    data = json.loads(r.stdout)
    assert data["config"] == str(cfg) and data["root"] == str(project.resolve())
    shown = {row["key"]: row for row in data["settings"]}
    assert shown["height.bricks"]["value"] == "textures/bricks_height.png"  # relative to the root, any cwd
    assert run_cli("config", "show", project / "models" / "nothing.gltf").returncode == 2


def test_every_option_field_is_a_key_without_more_code():
    """The keys follow ConvertOptions' fields: a field added later is a key at once."""
    import dataclasses

    keys = option_fields()
    assert keys["max-error"].name == "max_error" and keys["allow-outside-paths"].name == "allow_outside"
    assert keys["self-shadow"].name == "self_shadow" and "force" not in keys and "heights" not in keys
    hidden = {f.name for f in dataclasses.fields(ConvertOptions) if f.metadata.get("config") is False}
    assert {f.name for f in keys.values()} == {f.name for f in dataclasses.fields(ConvertOptions)} - hidden


def test_a_field_added_later_is_read_from_the_configuration(project, monkeypatch):
    """A list field (as the warning codes' error_on will be) works in the configuration at once."""
    import dataclasses

    from csm_assets.config import load as load_module

    @dataclasses.dataclass
    class Later(ConvertOptions):
        error_on: list[str] = dataclasses.field(default_factory=list)

    monkeypatch.setattr(load_module, "ConvertOptions", Later)
    cfg = write(project / "csm-assets.toml", "error-on = [\"W101\", \"W102\"]\n")
    (value,) = load(cfg).sections[0].values
    assert (value.key, value.target, value.value) == ("error-on", "error_on", ["W101", "W102"])
    bad = write(project / "csm-assets.toml", "error-on = [\"W101\", 3]\n")
    with pytest.raises(ConfigError, match=r":1: error-on: expected a list of text"):
        load(bad)


# ---- key_lines against the lines a writer put the keys on -----------------------------------

_BARE = st.from_regex(r"[A-Za-z_][A-Za-z0-9_-]{0,6}", fullmatch=True)
_QUOTED = st.text(st.characters(whitelist_categories=("L", "N"), whitelist_characters=" ./*-"), min_size=1,
                  max_size=8)


def _spell(key: str, quoted: bool) -> str:
    import re

    return json.dumps(key, ensure_ascii=False) if quoted or not re.fullmatch(r"[A-Za-z0-9_-]+", key) else key


VALUES = ["1", "true", '"a = b"', "[1,\n  2,\n]", '"""x\ny = 1\n"""', '{ a = 1, b = "c" }', "'q' # c = 1"]


@given(st.lists(st.tuples(st.booleans(), _BARE | _QUOTED,
                          st.lists(st.tuples(_BARE, st.sampled_from(VALUES)), min_size=1, max_size=4,
                                   unique_by=lambda kv: kv[0])),
                min_size=1, max_size=4, unique_by=lambda t: t[1]))
def test_key_lines_finds_the_line_a_writer_put_each_key_on(tables):
    """A writer that knows where it puts each key (bare and quoted table names, values over
    several lines, strings and comments that look like keys) against :func:`key_lines`."""
    import tomllib

    lines, want = [], {}
    for quoted, name, items in tables:
        lines.append(f"[scenes.{_spell(name, quoted)}]")
        want[("scenes", name)] = len(lines)
        for key, value in items:
            want[("scenes", name, key)] = len(lines) + 1
            lines.extend(f"{key} = {value}".split("\n"))
        lines.append("")
    source = "\n".join(lines)
    tomllib.loads(source)  # the writer wrote TOML
    found = key_lines(source)
    for path, line in want.items():
        assert found.get(path) == line, (path, source)
    assert line_of(found, ("scenes", tables[0][1], "nope", "deeper")) == want[("scenes", tables[0][1])]


def test_key_lines_of_dotted_and_inline_keys():
    source = 'a.b = 1\n"c.d" = 2\n[t]\nx = { y = 1 }\n[[arr]]\nk = 1\n[[arr]]\nk = 2\n'
    lines = key_lines(source)
    assert lines[("a", "b")] == 1 and lines[("c.d",)] == 2 and lines[("t", "x")] == 4
    assert line_of(lines, ("t", "x", "y")) == 4 and lines[("arr", 1, "k")] == 8


def test_paths_in_a_configuration_are_relative_to_its_file(project, tmp_path):
    """A configuration in models/ names ../textures; from any working directory the same file."""
    write(project / "models" / "csm-assets.toml", 'height = { bricks = "../textures/bricks_height.png" }\n')
    for cwd in (tmp_path, project, project / "textures"):
        r = run_cli("config", "show", project / "models" / "brick_wall.obj", "--json", cwd=cwd)
        shown = {row["key"]: row["value"] for row in json.loads(r.stdout)["settings"]}
        assert shown["height.bricks"] == "../textures/bricks_height.png"  # root: the configuration's folder


def test_samples_scene_has_no_configuration():
    """The project's own samples are not under a csm-assets configuration (its pyproject has none)."""
    assert find_config(SAMPLES / "brick_wall.gltf") is None
    assert shutil.which("git") is None or project_root(SAMPLES / "brick_wall.gltf") == SAMPLES.parent.resolve()


# ---- the warning policy (strict, error-on, ignore) ---------------------------------------------

def test_warning_policy_keys_decide_as_the_flags_do(tmp_path):
    """The USD wall with USD's default subdivision scheme (CSM208, informational): ``error-on``
    in the configuration fails convert, hook and check (exit 3) as ``--error-on`` does, a
    scene table's ``ignore`` replaces it, the command line's flags replace both, and none of
    them makes fresh outputs stale."""
    from usd_stages import edit, wall_folder

    folder = wall_folder(tmp_path)
    (tmp_path / ".git").mkdir()
    scene = edit(folder / "brick_wall.usda",
                 lambda st: st.GetPrimAtPath("/World/wall").GetAttribute("subdivisionScheme").Clear())
    cfg = write(tmp_path / "csm-assets.toml", """
        strict = true
        error-on = ["csm208"]
        """)
    o = Resolver().options(scene)
    assert (o.strict, o.error_on, o.ignore) == (True, ("CSM208",), ())
    r = run_cli("hook", scene)
    assert r.returncode == 3 and "--error-on (CSM208)" in r.stderr, r
    assert not (folder / "brick_wall_usda_csm").exists()
    r = run_cli("hook", scene, "--error-on", "CSM205")  # the command line's list replaces the file's
    assert r.returncode == 1 and "info: CSM208" in r.stderr, r
    assert run_cli("check", scene).returncode == 3  # fresh, made with a warning the file makes an error
    assert run_cli("check", scene, "--ignore", "CSM208").returncode == 2  # both in error-on and ignore
    cfg.write_text(cfg.read_text() + '\n[scenes."in/*.usda"]\nerror-on = []\nignore = ["CSM208"]\n')
    r = run_cli("check", scene)
    assert r.returncode == 0 and "CSM208" not in r.stderr, r  # the policy never makes outputs stale
    r = run_cli("config", "show", scene, "--json")
    shown = {row["key"]: row for row in json.loads(r.stdout)["settings"]}
    assert shown["ignore"]["value"] == ["CSM208"] and shown["ignore"]["source"] == f"{cfg.resolve()}:6"
    assert shown["strict"]["value"] is True and shown["strict"]["source"] == f"{cfg.resolve()}:1"

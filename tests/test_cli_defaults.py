"""Every CLI default is the library's (read from it, never restated) and --help shows it."""

from __future__ import annotations

import inspect

import pytest

from csm_assets.bench import cones as bench, trade
from csm_assets.convert import pipeline as convert
from csm_assets.verify import maps as verify
from csm_assets import view
from csm_assets.cli import COMMANDS, build_parser
from csm_assets.stepmap import DEFAULTS


def library(func, name):
    return inspect.signature(func).parameters[name].default


CASES = [  # (argv, dest, the library's value, how --help shows it)
    (["stepmap", "x.png", "-o", "o.png"], "max_ratio", DEFAULTS.max_ratio, None),
    (["stepmap", "x.png", "-o", "o.png"], "bilinear_safe", DEFAULTS.bilinear_safe, None),
    (["stepmap", "x.png", "-o", "o.png"], "cones", DEFAULTS.cones, f"(default {DEFAULTS.cones})"),
    (["convert", "x.gltf", "-o", "o"], "bits", convert.ConvertOptions.bits, "(default: per map, the fewest whose"),
    (["stepmap", "x.png", "-o", "o.png"], "bits", None, "else the fewest bits whose rounding"),
    (["convert", "x.gltf", "-o", "o"], "max_ratio", convert.ConvertOptions.max_ratio, None),
    (["convert", "x.gltf", "-o", "o"], "bilinear_safe", convert.ConvertOptions.bilinear_safe, None),
    (["check", "x.gltf"], "bits", convert.ConvertOptions.bits, None),
    (["hook"], "max_ratio", convert.ConvertOptions.max_ratio, None),
    (["verify", "x.png"], "size", None, f"(default {verify.RENDER_SIZE}"),  # None: verify's own, or --distance's
    (["verify", "x.png"], "max_error", library(verify.verify_step_map, "max_error"), None),
    (["verify", "x.png"], "depth", library(verify.verify_step_map, "depth"), None),
    (["verify", "x.png"], "max_iterations", library(verify.verify_step_map, "max_iterations"), None),
    (["verify", "x.png"], "bits", library(verify.verify_file, "bits"), None),
    (["bench", "trade", "x.png"], "size", library(trade.measure_trade, "size"), None),
    (["bench", "trade", "x.png"], "depth", library(trade.measure_trade, "depth"), None),
    (["bench", "trade", "x.png"], "max_iterations", library(trade.measure_trade, "max_iterations"), None),
    (["bench", "trade", "x.png"], "bits", [DEFAULTS.bits], None),
    (["bench", "cones"], "sizes", list(bench.SIZES), "(default 256 512 1024 2048)"),
    (["bench", "cones"], "timeout", library(bench.bench_cones, "timeout"), None),
    (["bench", "cones"], "repeat", library(bench.bench_cones, "repeat"), None),
    (["view", "x.gltf"], "port", library(view.serve, "port"), None),
]


SCENE_COMMANDS = {"convert", "check", "hook"}  # their setting flags parse to None: "not given"


@pytest.mark.parametrize("argv, dest, want, shown", CASES, ids=lambda v: v if isinstance(v, str) else None)
def test_cli_default_is_the_librarys(argv, dest, want, shown, capsys, tmp_path):
    args = build_parser().parse_args(argv)
    if argv[0] in SCENE_COMMANDS:  # the default is what a scene without a configuration gets
        from csm_assets.cli.scenes import resolver

        assert getattr(args, dest) is None
        assert resolver(args).settings(tmp_path / "x.gltf").settings[dest].value == want
    else:
        assert getattr(args, dest) == want
    if shown:
        with pytest.raises(SystemExit):
            build_parser().parse_args([*argv[: 2 if argv[0] == "bench" else 1], "--help"])
        assert shown in " ".join(capsys.readouterr().out.split())


def test_every_command_module_declares_and_runs():
    """The CLI is a table of modules, each with add(subparsers) and a run (or its sub-commands')."""
    names = build_parser()._subparsers._group_actions[0].choices  # argparse keeps them here
    assert set(names) == {"stepmap", "verify", "convert", "check", "hook", "config", "bench", "view", "blender"}
    for module in COMMANDS:
        assert callable(module.add) and module.__doc__


def test_relaxed_search_steps_default_is_one_constant(capsys):
    """verify (a map, and its --shadows) draws the relaxed variant with the search steps convert
    writes into relaxed materials: verify.RELAXED_DEFAULT_STEPS (docs: 2), shown in both helps."""
    assert verify.RELAXED_DEFAULT_STEPS == 2
    assert verify.map_steps("relaxed") == verify.default_steps("relaxed") == verify.RELAXED_DEFAULT_STEPS
    assert verify.map_steps("relaxed", 5) == 5 and verify.map_steps("fixed") == verify.STEPS
    for argv in (["verify", "--help"], ["convert", "--help"]):
        with pytest.raises(SystemExit):
            build_parser().parse_args(argv)
        assert f"relaxed {verify.RELAXED_DEFAULT_STEPS}" in " ".join(capsys.readouterr().out.split())


def test_verify_draws_a_relaxed_map_with_converts_search_steps(tmp_path, capsys):
    import json

    from conftest import GLTF_WALL, copy_samples, skip_without_gl

    from csm_assets.cli import main

    skip_without_gl()
    src = copy_samples(tmp_path / "in", GLTF_WALL)
    report = convert.convert(src / "brick_wall.gltf", tmp_path / "out", cones="relaxed", variant="relaxed")
    (step_map,) = report.step_maps.values()
    doc = json.loads((tmp_path / "out" / "brick_wall.gltf").read_text())
    written = doc["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["steps"]
    capsys.readouterr()
    assert main(["verify", str(step_map), "--variant", "relaxed", "--views", "60/30", "--size", "16", "--json",
                 "--shadows", "--light-elevation", "45", "--light-azimuth", "0"]) in (0, 1)
    data = json.loads(capsys.readouterr().out)
    assert data["variants"][0]["steps"] == data["shadows"]["steps"] == written == verify.RELAXED_DEFAULT_STEPS

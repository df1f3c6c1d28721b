"""The ``[scenes."GLOB"]`` matcher (:mod:`csm_assets.config.globs`) against pathlib's own glob
on random trees, and through symbolic links (loops cost one visit)."""

from __future__ import annotations

from pathlib import Path

from conftest import OBJ_WALL, copy_samples, examples
from hypothesis import given, strategies as st

from csm_assets.config.globs import Glob, matching_files
from csm_assets.convert.pipeline import SCENE_FORMATS

_PARTS = st.sampled_from(["*", "**", "a", "b", "?", "*.gltf", "*.obj", "x.gltf", "[ab]", ".*", "*.GLTF", "a*", ".h"])
_TREE_NAMES = ["a", "b", "ab", ".h", "x.gltf", "y.obj", "A.GLTF", "n.txt"]
_TREES = st.recursive(st.sampled_from(["file"]), lambda inner: st.dictionaries(st.sampled_from(_TREE_NAMES), inner,
                                                                             max_size=4), max_leaves=20)


def _build(folder: Path, tree) -> None:
    for name, sub in tree.items():
        if sub == "file":
            (folder / name).write_text("{}")
        else:
            (folder / name).mkdir()
            _build(folder / name, sub)


@examples(1.0)
@given(tree=st.dictionaries(st.sampled_from(_TREE_NAMES), _TREES, max_size=5),
       globs=st.lists(st.lists(_PARTS, min_size=1, max_size=5).map("/".join), min_size=1, max_size=4))
def test_globs_match_what_pathlib_matches(tmp_path_factory, tree, globs):
    """The one-walk automaton against pathlib's own glob on random trees (no links): the same
    scene files for every glob, ``**`` repeated or not."""
    folder = tmp_path_factory.mktemp("tree")
    _build(folder, tree)
    want = [{p.resolve() for p in folder.glob(g) if p.suffix.lower() in SCENE_FORMATS and p.is_file()}
            for g in globs]
    assert matching_files(folder, globs, SCENE_FORMATS) == want


def test_link_loops_cost_one_visit_and_links_are_entered_by_name_only(tmp_path):
    """A folder that links back to its parent: ``*/*/...`` follows it (as pathlib does) without
    a walk per way round; ``**`` never enters a link (as pathlib does)."""
    models = copy_samples(tmp_path / "models", OBJ_WALL)
    (models / "loop").symlink_to("..")
    (models / "back").symlink_to(".")
    (tmp_path / "linked").symlink_to("models")
    scene = (models / "brick_wall.obj").resolve()
    star = "/".join(["*"] * 24) + "/*.obj"
    found = matching_files(tmp_path, ["**/*.obj", "linked/*.obj", star, "models/loop/models/back/*.obj"],
                           SCENE_FORMATS)
    assert found == [{scene}] * 4


def test_repeated_double_stars_are_one_and_a_trailing_one_matches_folders_only(tmp_path):
    assert Glob("**/**/./**//models/**/**").parts == ["**", "models", "**"]
    copy_samples(tmp_path / "models", OBJ_WALL)
    assert matching_files(tmp_path, ["models/**", "**", "**/*.OBJ", "models/brick_wall.obj"], SCENE_FORMATS) == \
        [set(), set(), set(), {(tmp_path / "models" / "brick_wall.obj").resolve()}]

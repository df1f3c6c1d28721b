"""A converted glTF is read back (verify) with its uvs placed by the step map's own
textureInfo: its texCoord and KHR_texture_transform, as convert placed the heights and as
the three.js plugin draws it, even where the material has no other texture to borrow a
placement from."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from attack import assert_clean_run, run_cli
from view_scenes import cylinder_scene

TRANSFORM = {"scale": [2.0, 3.0], "rotation": 0.5, "offset": [0.1, 0.2]}


def transformed_cylinder(tmp_path: Path) -> Path:
    """The converted cylinder whose only texture, the heights, is placed by TRANSFORM."""
    src = cylinder_scene(tmp_path / "src")
    doc = json.loads(src.read_text())
    info = doc["materials"][0]["extensions"]["KHR_materials_displacement"]["displacementGeometryTexture"]
    info["extensions"] = {"KHR_texture_transform": TRANSFORM}
    doc["extensionsUsed"].append("KHR_texture_transform")
    src.write_text(json.dumps(doc))
    assert_clean_run(run_cli("convert", src, "-o", tmp_path / "out", "-q"))
    return tmp_path / "out" / src.name


def test_verify_reads_uvs_through_the_step_maps_transform(tmp_path):
    from csm_assets.formats import gltf
    from csm_assets.formats import gltf_container as gc
    from csm_assets.verify.scene import read_converted

    out = transformed_cylinder(tmp_path)
    doc = gc.load(out)
    info = doc.json["materials"][0]["extensions"]["EXT_materials_cone_step_mapping"]["stepMapTexture"]
    assert info["extensions"]["KHR_texture_transform"] == TRANSFORM
    raw = gc.read_accessor(doc, doc.json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"])
    uvs = read_converted(out)[0].meshes[0].uvs
    np.testing.assert_allclose(uvs, gltf.apply_transform(raw.astype(np.float64), TRANSFORM), atol=1e-6)
    assert np.abs(uvs - raw).max() > 0.5  # the transform moved them

"""Attacks on ``csm-assets view`` with bad values in a material's EXT_materials_cone_step_mapping:
every field of the extension's schema given a wrong type, a huge, negative, NaN-like or
prototype-key value. Each is a CSM504 warning naming the material and the page shows that
material plain; the scene is still served (never an internal error)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

from conftest import GLTF_WALL, copy_samples
from csm_assets.view import load_scene
from csm_assets.warning_codes import Policy

BIG = "1" + "0" * 400  # a JSON integer past float's range
# (change, what the warning says); the value "__RAW__" is replaced by the JSON text after the bar
BAD = [
    ({"variant": "__proto__"}, "variant '__proto__' is none of"),
    ({"variant": "constructor"}, "variant 'constructor' is none of"),
    ({"variant": "toString"}, "variant 'toString' is none of"),
    ({"variant": "hasOwnProperty"}, "variant 'hasOwnProperty' is none of"),
    ({"variant": 3}, "variant must be a string"),
    ({"variant": "x" * 100_000}, "(100002 characters)"),
    ({"steps": 1e9}, "steps 1000000000.0 is outside 0..127"),
    ({"steps": -1}, "steps -1 is outside 0..127"),
    ({"steps": 2.5}, "steps must be an integer"),
    ({"steps": "8"}, "steps must be an integer"),
    ({"steps": "__RAW__|" + BIG}, "(401 characters) is outside 0..127"),
    ({"depthScale": -1}, "depthScale must be a finite number >= 0"),
    ({"depthScale": "0.1"}, "depthScale must be a number"),
    ({"depthScale": True}, "depthScale must be a number"),
    ({"depthScale": None}, "no depthScale"),
    ({"depthScale": "__RAW__|" + BIG}, "depthScale must be a finite number"),
    ({"maxRatio": 0}, "maxRatio must be a finite number > 0"),
    ({"maxRatio": "__RAW__|-" + BIG}, "maxRatio must be a finite number"),
    ({"maxRatio": {"__proto__": 1}}, "maxRatio must be a number"),
    ({"tile": [True]}, "tile must be two booleans"),
    ({"tile": {"0": True, "1": True}}, "tile must be two booleans"),
    ({"tile": [1, 0]}, "tile must be two booleans"),
    ({"heightScale": "__RAW__|" + BIG}, "heightScale must be a finite number"),
    ({"heightOffset": []}, "heightOffset must be a number"),
    ({"minStep": 0}, "minStep 0 is outside (0, 1] texels"),
    ({"minStep": 2}, "minStep 2 is outside (0, 1] texels"),
    ({"minStep": "__RAW__|" + BIG}, "minStep must be a finite number"),
    ({"selfShadow": "yes"}, "selfShadow must be a boolean"),
    ({"selfShadow": 1}, "selfShadow must be a boolean"),
    ({"lightSize": -0.5}, "lightSize must be a finite number >= 0"),
    ({"lightSize": "__RAW__|" + BIG}, "lightSize must be a finite number"),
    ({"stepMapTexture": {"index": 0, "constructor": 1}, "variant": "prototype"}, "variant 'prototype' is none of"),
    # within the schema but past the shader's 32-bit floats
    ({"depthScale": 1e308}, "depthScale 1e+308 is beyond the shader's 32-bit floats"),
    ({"lightSize": 1e39, "maxRatio": 1e300}, "maxRatio 1e+300, lightSize 1e+39 are beyond"),
    ({"stepMapTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [1e300, 1]}}}},
     "stepMapTexture's scale 1e+300 is beyond"),
    # an integer past 32-bit floats (JSON without a point): the page's check refuses it as well
    ({"stepMapTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [10 ** 39, 1]}}}},
     "stepMapTexture's scale 1e+39 is beyond"),
]


def scene(tmp_path, changes):
    """brick_wall.gltf with one material per change (the first is the wall's own)."""
    folder = copy_samples(tmp_path / "scene", GLTF_WALL)
    doc = json.loads((folder / "brick_wall.gltf").read_text())
    raws = []
    for i, change in enumerate(changes):
        ext = {"stepMapTexture": {"index": 0}, "depthScale": 0.05}
        for key, value in change.items():
            if isinstance(value, str) and value.startswith("__RAW__|"):
                raws.append(value.split("|", 1)[1])
                value = f"__RAW{len(raws) - 1}__"
            if value is None:
                ext.pop(key)
            else:
                ext[key] = value
        material = doc["materials"][0] if i == 0 else {"name": f"m{i}"}
        material.setdefault("extensions", {})["EXT_materials_cone_step_mapping"] = ext
        if i:
            doc["materials"].append(material)
    text = json.dumps(doc)
    for i, raw in enumerate(raws):
        text = text.replace(f'"__RAW{i}__"', raw)
    (folder / "brick_wall.gltf").write_text(text)
    return folder / "brick_wall.gltf"


@pytest.mark.parametrize("change, said", BAD, ids=[str(i) for i in range(len(BAD))])
def test_every_field_is_a_warning_and_the_plain_material(tmp_path, change, said):
    view = load_scene(scene(tmp_path, [change]))
    (notice,) = [w for w in view.warnings if w.code == "CSM504"]
    assert said in str(notice) and "'bricks'" in str(notice) and "without relief" in str(notice), notice
    assert len(str(notice)) < 400, str(notice)  # one readable line, not the value
    assert Policy().level("CSM504") == "warning"
    json.dumps(view.info())  # what /api/scene.json answers


def test_a_transform_past_float_is_a_clean_error(tmp_path):
    """A 400-digit integer in the step map's KHR_texture_transform: the reader's FormatError naming
    its JSON pointer (exit 3, as for 1e999), not an OverflowError."""
    from csm_assets.errors import FormatError

    path = scene(tmp_path, [{"stepMapTexture": {"index": 0, "extensions": {"KHR_texture_transform": {
        "offset": ["__RAW__|" + BIG, 0]}}}}])
    text = path.read_text()
    path.write_text(text.replace('"__RAW__|' + BIG + '"', BIG))
    with pytest.raises(FormatError, match="KHR_texture_transform/offset: expected an array of 2 finite numbers"):
        load_scene(path)


def test_view_serves_a_scene_of_bad_materials(tmp_path):
    """The real CLI: each of the named cases (and the rest) one warning line naming its material,
    then the scene is served; Ctrl-C ends it as usual (130), no internal error."""
    from test_view import get

    path = scene(tmp_path, [c for c, _ in BAD])
    proc = subprocess.Popen([sys.executable, "-m", "csm_assets", "view", str(path), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert "viewing brick_wall.gltf at http://127.0.0.1:" in line, (line, proc.stderr.read())
        port = int(line.split("127.0.0.1:")[1].split("/")[0])
        status, _, body = get(port, "/api/scene.json")
        assert status == 200 and sum("CSM504" in w for w in json.loads(body)["warnings"]) == len(BAD)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "internal error" not in err and "Traceback" not in err, err
    warned = [x for x in err.splitlines() if x.startswith("csm-assets: warning: CSM504")]
    assert len(warned) == len(BAD), err
    for i, (_, said) in enumerate(BAD):
        name = "'bricks'" if i == 0 else f"'m{i}'"
        assert any(said in w and f": {name}: " in w for w in warned), (name, said, err)

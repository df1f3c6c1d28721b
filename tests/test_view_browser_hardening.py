"""The viewer page against hostile scenes, in headless chromium: extension values that break
the schema (wrong types, out of range, past 32-bit floats, ``variant`` "constructor"/"toString"/"__proto__"), a
step map that does not load, a backslash uri, a URL swapped in after start-up. The bad
material falls back to its plain material with one console warning; the other material
keeps its relief; no exception; the page's CSP reports no violation in normal use.

The scene is served once per test (``csm-assets view``); cases rewrite the glTF between page
loads, which the server reads afresh on each request."""

from __future__ import annotations

import json
import shutil
import socket

import numpy as np
import pytest

from cdp import Chromium
from view_page import SIZE, browser_raw, camera, convert, needs_browser, serving
from view_scenes import two_material_scene

pytestmark = pytest.mark.browser
EXT = "EXT_materials_cone_step_mapping"
VIEW = ((0.3, 0.6, 1.6), (0.0, 0.0, 0.0))


@pytest.fixture(scope="module", autouse=True)
def _needs_browser():
    needs_browser()


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    return convert(two_material_scene(tmp_path_factory.mktemp("src")), tmp_path_factory.mktemp("out"))


@pytest.fixture
def scene(converted, tmp_path):
    shutil.copytree(converted.parent, tmp_path / "s")
    return tmp_path / "s" / converted.name


def _console(b: Chromium, kind: str) -> list[str]:
    return [" ".join(str(a.get("value", a.get("description", ""))) for a in e["params"]["args"])
            for e in b.events if e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == kind]


def _exceptions(b: Chromium) -> list:
    return [e["params"] for e in b.events if e.get("method") == "Runtime.exceptionThrown"]


def _open(b: Chromium, url: str) -> dict:
    b.goto(url)
    info = b.eval("window.csmViewer.ready", timeout=120)
    assert "error" not in info, info
    return info


def _relief_hits(b: Chromium) -> tuple[int, int]:
    """Pixels drawn (the relief's hits, or a plain material's), on the left (bricks) and right
    (cobbles) third of the raw hit view."""
    raw = browser_raw(b, camera(*VIEW), "rawUv")
    hit = np.rint(raw[..., 3]) == 1
    return int(hit[:, : SIZE[0] // 3].sum()), int(hit[:, -SIZE[0] // 3:].sum())


BAD = {
    "steps 1e9": {"steps": 1000000000}, "depthScale -1": {"depthScale": -1}, "depthScale abc": {"depthScale": "abc"},
    "maxRatio 0": {"maxRatio": 0}, "tile yes": {"tile": "yes"}, "tile one": {"tile": [True]},
    "minStep -5": {"minStep": -5}, "minStep 2": {"minStep": 2}, "variant constructor": {"variant": "constructor"},
    "variant toString": {"variant": "toString"}, "variant __proto__": {"variant": "__proto__"},
    "variant hasOwnProperty": {"variant": "hasOwnProperty"}, "steps 2.5": {"steps": 2.5},
    "selfShadow yes": {"selfShadow": "yes"}, "lightSize -1": {"lightSize": -1}, "no depthScale": {"depthScale": None},
    "no step map": {"stepMapTexture": None}, "step map index 99": {"stepMapTexture": {"index": 99}},
    "step map index -1": {"stepMapTexture": {"index": -1}},
    "transform scale big": {"stepMapTexture": {"index": 3, "extensions": {"KHR_texture_transform": {"scale": "big"}}}},
    "not an object": 5,
    # past float32 (the shader's floats) or past float64 (a 400-digit integer: Infinity in JSON.parse)
    "depthScale 1e308": {"depthScale": 1e308}, "lightSize 1e39": {"lightSize": 1e39},
    "steps 10**400": {"steps": 10 ** 400}, "maxRatio 10**400": {"maxRatio": 10 ** 400},
    "transform scale 1e300": {"stepMapTexture": {"index": 3, "extensions": {
        "KHR_texture_transform": {"scale": [1e300, 1]}}}},
}


def _rewrite(scene, change) -> None:
    doc = json.loads(scene.read_text())
    ext = doc["materials"][0]["extensions"]
    if not isinstance(change, dict):
        ext[EXT] = change
    else:
        for k, v in change.items():
            if v is None:
                ext[EXT].pop(k)
            else:
                ext[EXT][k] = v
    scene.write_text(json.dumps(doc))


def test_bad_extension_values_fall_back_with_one_warning(scene):
    good = scene.read_text()
    with serving(scene) as url, Chromium(*SIZE) as b:
        info = _open(b, url)
        assert [m["fallback"] for m in info["materials"]] == [None, None]
        bricks, cobbles = _relief_hits(b)
        assert bricks > 500 and cobbles > 500, (bricks, cobbles)
        for case, change in BAD.items():
            scene.write_text(good)
            _rewrite(scene, change)
            info = _open(b, url)
            fallbacks = {m["name"]: m["fallback"] for m in info["materials"]}
            assert fallbacks["cobbles"] is None, case
            why = fallbacks["bricks"]
            assert why and ("invalid extension" in why or "did not load" in why), (case, why)
            warned = [w for w in _console(b, "warning") if w.startswith(EXT)]
            assert len(warned) == 1 and "bricks" in warned[0], (case, warned)
            assert not _exceptions(b), (case, _exceptions(b))
            assert not _console(b, "error"), (case, _console(b, "error"))
            bricks, cobbles = _relief_hits(b)
            assert bricks > 500 and cobbles > 500, (case, bricks, cobbles)  # all drawn, cobbles with relief
        with pytest.raises(Exception, match="unknown variant"):
            b.eval("window.csmViewer.setVariant('toString')")
        for name in ("__proto__", "constructor", "toString"):  # never a prototype's property
            with pytest.raises(Exception, match="unknown debug view"):
                b.eval(f"window.csmViewer.setDebug('{name}')")


def test_a_missing_step_map_falls_back_and_the_rest_is_drawn(scene):
    with serving(scene) as url, Chromium(*SIZE) as b:
        (scene.parent / "bricks_height_csm.png").unlink()  # gone after start-up
        info = _open(b, url)
        fallbacks = {m["name"]: m["fallback"] for m in info["materials"]}
        assert fallbacks == {"bricks": "step map texture 3 did not load", "cobbles": None}, fallbacks
        warned = [w for w in _console(b, "warning") if w.startswith(EXT)]
        assert len(warned) == 1, warned
        assert not _exceptions(b), _exceptions(b)
        # the only error is three.js's own line about the image it could not load
        assert all("Couldn't load texture" in e for e in _console(b, "error")), _console(b, "error")
        bricks, cobbles = _relief_hits(b)
        assert bricks > 500 and cobbles > 500, (bricks, cobbles)
        shot = b.screenshot()
        assert len(shot) > 1000


def test_backslash_uri_and_no_csp_violation(scene):
    """A step map named ``sub\\\\cobbles_csm.png`` (as the readers accept) is found; in normal
    use the page's CSP blocks nothing and nothing is logged."""
    (scene.parent / "sub").mkdir()
    shutil.move(scene.parent / "cobbles_csm.png", scene.parent / "sub" / "cobbles_csm.png")
    doc = json.loads(scene.read_text())
    (image,) = [i for i in doc["images"] if i.get("uri") == "cobbles_csm.png"]
    image["uri"] = "sub\\cobbles_csm.png"
    scene.write_text(json.dumps(doc))
    with serving(scene) as url, Chromium(*SIZE) as b:
        b.call("Log.enable")
        info = _open(b, url)
        assert [m["fallback"] for m in info["materials"]] == [None, None]
        bricks, cobbles = _relief_hits(b)
        assert bricks > 500 and cobbles > 500
        logged = [e["params"]["entry"] for e in b.events if e.get("method") == "Log.entryAdded"]
        assert not logged, logged
        assert not _console(b, "warning") and not _console(b, "error") and not _exceptions(b)


def test_a_url_swapped_in_after_start_up_is_not_requested(scene):
    """The glTF rewritten while served to name another host's image: the page does not ask
    that host (the loader's URL check and the CSP), the material still draws."""
    with socket.socket() as beacon:
        beacon.bind(("127.0.0.1", 0))
        beacon.listen(4)
        beacon.settimeout(0.2)
        port = beacon.getsockname()[1]
        with serving(scene) as url, Chromium(*SIZE) as b:
            doc = json.loads(scene.read_text())
            (image,) = [i for i in doc["images"] if i.get("uri") == "bricks_color.png"]
            image["uri"] = f"HTTP://127.0.0.1:{port}/beacon.png"
            scene.write_text(json.dumps(doc))
            info = _open(b, url)
            assert [m["fallback"] for m in info["materials"]] == [None, None]
            assert any("is not on this server" in w for w in _console(b, "warning")), _console(b, "warning")
            with pytest.raises(socket.timeout):
                beacon.accept()

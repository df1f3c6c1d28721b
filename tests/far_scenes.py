"""A relief seen far away in the browser, against ``verify --distance``'s supersampled exact
reference, shared by tests/test_view_browser_distance.py and benchmarks/distance_browser.py.

``relief_quad_scene`` writes a unit quad whose heights repeat across it (``ACROSS`` texels in all),
``bake_albedo`` makes a converted scene's base colour the baked N·L of its step map
(:func:`csm_assets.verify.distance.baked_lighting`, the quantity ``verify --distance`` compares).
``far_reference`` makes one view's moderngl side, the same for every engine: moderngl's emulation of
the shading (:func:`~csm_assets.verify.distance_shading.footprint_image` on moderngl's render), one
unfiltered fetch at moderngl's hit, and the reference: the mean of the albedo at the exact hits
(:func:`~csm_assets.verify.trace.trace_heightfield`) of ``sub``² rays through each pixel, their
texture-space rays from moderngl's render of the same camera at ``sub`` times the size.
``far_images`` adds a browser's drawing of that view, unlit (the plugin's ``rawAlbedo`` view: the
base colour as the relief fetched it, blended with its pixel quad as the lit colour is).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from view_page import FOV_DEG, browser_raw
from view_scenes import moderngl_draws, quad_geometry

ACROSS = 1536  # texels across the quad: 8 a pixel straight on from 1.4 away in a 288x192 view
DEPTH = 0.1  # the relief's depth in texture space (verify --distance's default)
NAME = "relief"


def relief_quad_scene(folder: Path, heights: np.ndarray, depth: float = DEPTH) -> Path:
    """Write ``far.gltf``: a unit quad at the origin facing +z, its material ``relief`` displaced by
    ``heights`` (float (H, W) in [0, 1], white high; a 16-bit PNG beside it) ``depth`` of the
    texture's width deep, the image repeated so that ``ACROSS`` texels span the quad each way
    (through KHR_texture_transform), a grey base colour image of the same placement; returns its
    path."""
    folder.mkdir(parents=True, exist_ok=True)
    h = np.clip(np.asarray(heights, np.float64), 0.0, 1.0)
    Image.fromarray(np.rint(h * 65535).astype(np.uint16)).save(folder / "height.png")
    Image.new("RGB", h.shape[::-1], (128, 128, 128)).save(folder / "albedo.png")
    place = {"KHR_texture_transform": {"scale": [ACROSS / h.shape[1], ACROSS / h.shape[0]]}}
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": NAME}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3,
                                    "material": 0}]}],
        **quad_geometry(),
        "images": [{"uri": "height.png"}, {"uri": "albedo.png"}],
        "textures": [{"source": 0}, {"source": 1}],
        "materials": [{"name": NAME, "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 1, "extensions": place}, "metallicFactor": 0},
            "extensions": {"KHR_materials_displacement": {
                "displacementGeometryTexture": {"index": 0, "extensions": place},
                "displacementGeometryFactor": depth * h.shape[1] / ACROSS}}}],
        "extensionsUsed": ["KHR_materials_displacement", "KHR_texture_transform"],
    }
    path = folder / "far.gltf"
    path.write_text(json.dumps(doc))
    return path


@dataclass
class Baked:
    """A converted scene's relief material with its base colour baked: the step map, its levels
    (1..n), the albedo the engines fetch (linear float64 (H, W): the sRGB PNG decoded) and the
    heights the reference traces."""

    packed: np.ndarray
    levels: tuple
    albedo: np.ndarray
    heights: np.ndarray


def bake_albedo(scene: Path, material: str = NAME) -> Baked:
    """Overwrite ``material``'s base colour image in the converted ``scene`` with the baked N·L of
    its step map at its own depth (8-bit sRGB, grey)."""
    from csm_assets.formats import read_step_map
    from csm_assets.step_levels import split_atlas
    from csm_assets.verify.distance import baked_lighting
    from csm_assets.verify.maps import sampled_heights

    doc = json.loads(scene.read_text())
    (m,) = [m for m in doc["materials"] if m["name"] == material]
    ext = m["extensions"]["EXT_materials_cone_step_mapping"]

    def file(info):
        return scene.parent / doc["images"][doc["textures"][info["index"]]["source"]]["uri"]

    packed = read_step_map(file(ext["stepMapTexture"]))
    levels = tuple(split_atlas(read_step_map(file(ext["stepMapLevelsTexture"])), packed.shape[:2])) \
        if "stepMapLevelsTexture" in ext else ()
    lit = baked_lighting(packed, ext["depthScale"])
    encoded = np.where(lit <= 0.0031308, 12.92 * lit, 1.055 * np.power(lit, 1 / 2.4) - 0.055)
    grey = np.rint(encoded * 255.0).astype(np.uint8)
    Image.fromarray(np.repeat(grey[..., None], 3, -1)).save(file(m["pbrMetallicRoughness"]["baseColorTexture"]))
    t = grey / 255.0
    linear = np.where(t <= 0.04045, t / 12.92, np.power((t + 0.055) / 1.055, 2.4))
    return Baked(packed, levels, linear, sampled_heights(packed))


def distance_for(texels: float, size: tuple) -> float:
    """The distance from the quad that puts ``texels`` texels a pixel across the screen at the
    centre of a ``size`` (w, h) view of :func:`far_camera`."""
    return texels * size[1] / (2.0 * ACROSS * math.tan(math.radians(FOV_DEG) / 2))


def far_camera(distance: float, elevation: float, azimuth: float = 30.0):
    """The camera ``distance`` from the quad's centre, ``elevation`` degrees above it and
    ``azimuth`` degrees around its normal from -y (off the texture's axes), its screen's rows
    level with the quad (the viewer tests' field of view)."""
    from csm_assets.render.renderer import Camera

    e, a = math.radians(elevation), math.radians(azimuth)
    eye = (distance * math.cos(e) * math.sin(a), -distance * math.cos(e) * math.cos(a), distance * math.sin(e))
    up = (0.0, 1.0, 0.0) if elevation >= 90.0 else (0.0, 0.0, 1.0)  # the screen's rows level with the quad
    return Camera(eye, (0.0, 0.0, 0.0), up=up, fov_deg=FOV_DEG)


def far_reference(scene: Path, baked: Baked, cam, size: tuple, sub: int = 8, window=np.s_[:, :]) -> dict:
    """The moderngl side of one view of the relief quad, the same for every engine: {"emulation",
    "one_fetch", "reference": float64 (h, w) images; "mask": bool (h, w), the pixels of ``window``
    the quad covers with all their sub-rays and where moderngl and the reference hit the relief;
    "texels": the texels a pixel spans across the screen at its centre; "camera": ``cam``}."""
    from csm_assets.render.renderer import STATUS_MISS
    from csm_assets.verify.distance_shading import bilinear, footprint_image, lit_chain, slope_chain
    from csm_assets.verify.trace import trace_heightfield

    w, h = size
    (res, _), = moderngl_draws(scene, cam, size, True)
    ok = res.covered & (res.status != STATUS_MISS)
    emulation = footprint_image(lit_chain(baked.albedo), res, ok, slope_chain(baked.packed, baked.levels))
    one = np.full((h, w), np.nan)
    one[ok] = bilinear(baked.albedo, res.hit_uv[ok])
    (fine, _), = moderngl_draws(scene, cam, (w * sub, h * sub), True)
    mask = np.zeros((h, w), bool)
    mask[window] = True
    mask &= ok & fine.covered.reshape(h, sub, w, sub).all(axis=(1, 3))
    rays = np.repeat(np.repeat(mask, sub, 0), sub, 1)
    dp, ds = fine.ray_uv[rays], fine.ray_dir[rays]
    uv, _, hit = trace_heightfield(baked.heights, np.column_stack([dp, np.ones(len(dp))]), ds * [1.0, 1.0, -1.0])
    pix = (np.argwhere(rays) // sub) @ [w, 1]
    total = np.bincount(pix[hit], bilinear(baked.albedo, uv[hit]), h * w)
    count = np.bincount(pix[hit], minlength=h * w)
    reference = np.full(h * w, np.nan)
    reference[count > 0] = total[count > 0] / count[count > 0]
    mask &= (count > 0).reshape(h, w)
    cols, rows = baked.packed.shape[1], baked.packed.shape[0]
    across = float(np.hypot(*((res.ray_uv[h // 2, w // 2] - res.ray_uv[h // 2, w // 2 - 1]) * [cols, rows])))
    return {"emulation": emulation, "one_fetch": one, "reference": reference.reshape(h, w), "mask": mask,
            "texels": across, "camera": cam}


def far_images(b, reference: dict) -> dict:
    """:func:`far_reference`'s view drawn by the page ``b`` (a loaded Chromium): its images and
    "browser", the rawAlbedo view's float64 (h, w) image; "mask" narrowed to where the browser drew
    the relief."""
    cam = reference["camera"]
    drawn = np.rint(browser_raw(b, cam, "rawUv")[..., 3]) == 1
    return {**reference, "browser": browser_raw(b, cam, "rawAlbedo")[..., 0].astype(np.float64),
            "mask": reference["mask"] & drawn}


def rmse(a, b, mask) -> float:
    """The RMS of ``a - b`` over ``mask``."""
    return float(np.sqrt(np.mean((a[mask] - b[mask]) ** 2)))

"""The views verify draws a scene's primitives from: automatic ones around each
primitive, and the scene's own cameras (glTF cameras, USD cameras).

Automatic views (:func:`auto_views`): the camera orbits the primitive's bounding-box
centre at a distance that fits its bounding sphere in a 40 degree field of view.
Elevations are measured from the plane perpendicular to the primitive's facing axis,
the area-weighted mean of its triangles' normals (90: looking straight at it,
10: grazing); when those normals cancel (closed or strongly curved shapes, where every
angle shows somewhere anyway) the axis is the one the bounding box is thinnest along.
"""

from __future__ import annotations

import math

import numpy as np

from ..render.camera import Camera, frame_camera, orbit_camera

FOV_DEG = 40.0
# (elevation, azimuth) in degrees: 90 looks straight down, 10 grazes (verify's views of maps and scenes)
DEFAULT_VIEWS = ((90.0, 0.0), (70.0, 30.0), (50.0, 120.0), (35.0, 200.0), (20.0, 290.0), (10.0, 45.0))


def view_camera(radius: float, elevation: float, azimuth: float):
    """The camera of a view of the unit quad: orbiting it, near enough at grazing views to fill the frame."""
    return orbit_camera(elevation, azimuth, 2 * radius * (1.0 + 0.8 * math.sin(math.radians(elevation))),
                        fov_deg=FOV_DEG)


def facing_axis(positions, normals) -> np.ndarray:
    """Unit ``(3,)``: the area-weighted mean facing of triangles given as corner arrays
    ``(3F, 3)`` (normals orient each face), or the bounding box's thinnest axis."""
    p = np.asarray(positions, np.float64).reshape(-1, 3, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3, 3).sum(axis=1)
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # length: twice the area
    face *= np.where(np.einsum("ij,ij->i", face, n) < 0, -1.0, 1.0)[:, None]
    total = np.linalg.norm(face, axis=1).sum()
    mean = face.sum(axis=0)
    if total > 0 and np.linalg.norm(mean) > 0.3 * total:
        return mean / np.linalg.norm(mean)
    axis = np.zeros(3)
    axis[int(np.argmin(np.ptp(p.reshape(-1, 3), axis=0)))] = 1.0
    return axis


def auto_views(positions, normals, views) -> list[tuple[float, float, Camera]]:
    """``(elevation, azimuth, camera)`` per (elevation, azimuth) of ``views`` around the
    primitive of corner arrays ``positions``, ``normals`` ``(3F, 3)``."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(float(np.linalg.norm(p - centre, axis=1).max()), 1e-9)
    distance = 1.1 * radius / math.sin(math.radians(FOV_DEG / 2))
    axis = facing_axis(positions, normals)
    return [(float(el), float(az), frame_camera(centre, axis, el, az, distance, FOV_DEG)) for el, az in views]


# --- the scene's own cameras --------------------------------------------------------------

def gltf_cameras(doc) -> tuple[list[tuple[str, Camera]], dict[int, np.ndarray]]:
    """The perspective cameras of a glTF document's default scene (``[(name, Camera)]``),
    and the world matrix ``(4, 4)`` of the first node showing each mesh index."""
    nodes = doc.json.get("nodes", [])
    scenes = doc.json.get("scenes", [])
    roots = scenes[doc.json.get("scene", 0)].get("nodes", []) if scenes else range(len(nodes))
    cameras, models = [], {}
    stack = [(int(i), np.eye(4)) for i in roots]
    seen = set()
    while stack:
        i, parent = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue
        seen.add(i)
        node = nodes[i]
        world = parent @ _node_matrix(node)
        if isinstance(node.get("mesh"), int):
            models.setdefault(node["mesh"], world)
        cam = _gltf_camera(doc, node, world)
        if cam is not None:
            cameras.append(cam)
        stack.extend((int(c), world) for c in node.get("children", []))
    return cameras, models


def _node_matrix(node) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T  # glTF is column-major
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), np.float64)
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def _gltf_camera(doc, node, world):
    cams = doc.json.get("cameras", [])
    i = node.get("camera")
    if not isinstance(i, int) or not 0 <= i < len(cams) or cams[i].get("type") != "perspective":
        return None
    persp = cams[i].get("perspective", {})
    eye = world[:3, 3]
    forward = -world[:3, 2] / max(np.linalg.norm(world[:3, 2]), 1e-12)
    up = world[:3, 1] / max(np.linalg.norm(world[:3, 1]), 1e-12)
    near = float(persp.get("znear", 0.01))
    name = cams[i].get("name") or node.get("name") or f"camera{i}"
    return name, Camera(tuple(eye), tuple(eye + forward), tuple(up), math.degrees(float(persp.get("yfov", 0.8))),
                        near, float(persp.get("zfar", near * 1e5)))


def usd_cameras(stage) -> tuple[list[tuple[str, Camera]], dict[str, np.ndarray]]:
    """The cameras of a USD stage, and the world matrix of each mesh prim (by path), in
    the stage's own units and up axis (cameras and meshes share them). ``stage``: a stage, or
    the USD reader's ``Scene.source``, which holds one."""
    from pxr import Usd, UsdGeom

    stage = getattr(stage, "stage", stage)
    t = Usd.TimeCode.Default()
    cameras, models = [], {}
    cache = UsdGeom.XformCache(t)
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            models[str(prim.GetPath())] = np.asarray(cache.GetLocalToWorldTransform(prim), np.float64).T
        elif prim.IsA(UsdGeom.Camera):
            cam = UsdGeom.Camera(prim).GetCamera(t)
            if cam.projection != cam.Perspective:
                continue
            m = np.asarray(cache.GetLocalToWorldTransform(prim), np.float64).T
            eye, forward, up = m[:3, 3], -m[:3, 2], m[:3, 1]
            near, far = cam.clippingRange.min, cam.clippingRange.max
            fov = cam.GetFieldOfView(cam.FOVVertical)
            cameras.append((prim.GetName(), Camera(tuple(eye), tuple(eye + forward / np.linalg.norm(forward)),
                                                   tuple(up / np.linalg.norm(up)), float(fov), float(near),
                                                   float(far))))
    return cameras, models

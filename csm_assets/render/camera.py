"""Perspective cameras: view and projection matrices, the world rays through pixel centres,
orbits around a point, and a camera looking along a frame (any up axis)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    """A perspective camera (frozen).

    Attributes:
        eye (tuple): world position ``(x, y, z)``.
        target (tuple): the world point it looks at.
        up (tuple): world up; not parallel to the view direction.
        fov_deg (float): vertical field of view in degrees.
        near (float): near clipping distance (> 0).
        far (float): far clipping distance.
    """

    eye: tuple
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 0.0, 1.0)
    fov_deg: float = 40.0
    near: float = 0.01
    far: float = 100.0

    def view(self) -> np.ndarray:
        """The ``(4, 4)`` world-to-eye matrix (OpenGL: looking down -z).

        Raises:
            ValueError: ``up`` parallel to the view direction.
        """
        e, t = np.asarray(self.eye, float), np.asarray(self.target, float)
        f = t - e
        f /= np.linalg.norm(f)
        r = np.cross(f, np.asarray(self.up, float))
        if np.linalg.norm(r) < 1e-9:
            raise ValueError(f"camera up {self.up} is parallel to the view direction")
        r /= np.linalg.norm(r)
        u = np.cross(r, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ e
        return m

    def projection(self, aspect: float) -> np.ndarray:
        """The ``(4, 4)`` OpenGL perspective projection.

        Args:
            aspect: width / height of the image.
        """
        f = 1.0 / np.tan(np.radians(self.fov_deg) / 2)
        n, fa = self.near, self.far
        return np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                         [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)], [0, 0, -1, 0]])

    def rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """World rays through the pixel centres, in image order (row 0 on top).

        Args:
            width: pixels.
            height: pixels.

        Returns:
            ``(origins, directions)``: float64 ``(height*width, 3)`` each, unit directions.
        """
        inv = np.linalg.inv(self.projection(width / height) @ self.view())
        x = (np.arange(width) + 0.5) / width * 2 - 1
        y = 1 - (np.arange(height) + 0.5) / height * 2
        xx, yy = np.meshgrid(x, y)
        far = np.stack([xx.ravel(), yy.ravel(), np.ones(xx.size), np.ones(xx.size)], axis=1) @ inv.T
        d = far[:, :3] / far[:, 3:] - np.asarray(self.eye, float)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.tile(np.asarray(self.eye, float), (xx.size, 1)), d


def orbit_camera(elevation_deg: float, azimuth_deg: float = 0.0, distance: float = 2.0,
                 fov_deg: float = 40.0, target=(0.0, 0.0, 0.0)) -> Camera:
    """A camera orbiting ``target`` above the z = 0 plane, z up.

    Args:
        elevation_deg: above the plane (90: straight down).
        azimuth_deg: around z, from +x.
        distance: from ``target``, world units.
        fov_deg: vertical field of view.
        target: the world point looked at.
    """
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    off = distance * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    up = (0.0, 1.0, 0.0) if abs(np.cos(e)) < 1e-6 else (0.0, 0.0, 1.0)
    return Camera(tuple(np.asarray(target, float) + off), tuple(target), up, fov_deg)


def frame_camera(centre, axis, elevation_deg: float, azimuth_deg: float, distance: float,
                 fov_deg: float = 40.0) -> Camera:
    """A camera looking at ``centre`` of a surface facing ``axis`` (any up axis).

    Args:
        centre: the world point looked at.
        axis: the surface's normal (need not be unit length).
        elevation_deg: above the plane perpendicular to ``axis`` (90: along -axis, straight
            on; near 0: grazing).
        azimuth_deg: around ``axis``, from a fixed direction perpendicular to it.
        distance: from ``centre``, world units; near and far planes follow it.
        fov_deg: vertical field of view.
    """
    n = np.asarray(axis, float)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, n)
    x /= np.linalg.norm(x)
    y = np.cross(n, x)
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    direction = np.cos(e) * (np.cos(a) * x + np.sin(a) * y) + np.sin(e) * n
    c = np.asarray(centre, float)
    up = y if abs(np.cos(e)) < 1e-6 else n
    near = max(distance * 1e-3, 1e-6)
    return Camera(tuple(c + distance * direction), tuple(c), tuple(up), fov_deg, near, distance * 4 + near)

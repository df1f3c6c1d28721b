"""MikkTSpace-compatible tangent frames for triangle meshes, and corner welding.

``mikktspace_tangents`` follows Morten Mikkelsen's reference ``mikktspace.c``
(``genTangSpaceDefault``: 180 degree threshold) step by step, for triangles:

1. Corners are identified by their exact float32 (position, normal, uv); ``-0 == +0``,
   a corner holding a NaN is never identified with another.
2. Triangles with two exactly equal corner positions are degenerate: they are left
   out and afterwards copy the frame of the first healthy corner identified with
   each of their corners (if none, MikkTSpace's default frame).
3. Every healthy triangle gets the uv derivatives ``dP/ds`` and ``dP/dt`` (eq. 18-19
   of the thesis) in float32, the sign of its uv area (orientation) and is marked
   "group with anything" when the uv area or a derivative is zero.
4. Triangles sharing an edge (same two identified corners, opposite winding) are
   neighbours. Around every corner, the neighbours with the same orientation form a
   group (a mirrored uv island or a uv seam splits groups); "group with anything"
   triangles adopt the orientation of the first group that reaches them.
5. A group's frame is the sum of its triangles' derivatives projected onto the plane
   of the corner normal, weighted by the corner angle, normalized.

The result is MikkTSpace's tangent and sign (``bitangent = sign * cross(n, t)``, the
glTF ``TANGENT`` convention). Where MikkTSpace leaves a frame undefined (zero tangent,
its default ``(1, 0, 0)`` with sign -1 on isolated degenerate triangles, NaN input),
the default ``orthonormalize=True`` projects onto the normal plane and falls back to
the coordinate axis least aligned with the normal, so every output is a unit vector
orthogonal to the normal with ``w = +-1``. Quads are not taken: triangulate first.
"""

from __future__ import annotations

import math
from typing import Mapping, NamedTuple

import numpy as np
from numba import njit

_F32 = np.float32
_ZERO = np.float32(0.0)
_FLT_MIN = np.float32(np.finfo(np.float32).tiny)
# genTangSpaceDefault: cos(180 deg) computed as mikktspace.c does, in float.
_THRES_COS = np.float32(math.cos(np.float32(np.float32(180.0) * np.float32(math.pi))
                                  / np.float32(180.0)))


def mikktspace_tangents(positions, normals, uvs, faces=None, *, flip_v: bool = False,
                        orthonormalize: bool = True) -> np.ndarray:
    """Per-corner MikkTSpace tangents of a triangle mesh.

    positions, normals: ``(V, 3)``; uvs: ``(V, 2)``; any float dtype, used as float32.
    faces: int ``(F, 3)`` indices into those arrays, or None when they are an unindexed
    triangle list (``V = 3F`` rows, or ``(F, 3, k)``). Normals should be unit length
    (MikkTSpace assumes so; they also take part in identifying corners).
    flip_v: the uvs have glTF's origin (top-left, v down). MikkTSpace works in
    OpenGL's convention (v up), so the generator then sees ``(u, -v)``, which gives
    the same frames as ``(u, 1 - v)`` (it only uses uv differences) without rounding;
    tangents are unchanged and ``w`` flips, so that ``cross(n, t) * w`` points up the
    image, as the glTF normal texture convention (+Y up) requires.
    orthonormalize: make every frame usable (see the module docstring); False returns
    MikkTSpace's values as they are.

    Returns float32 ``(F, 3, 4)``: xyz the tangent, w the handedness (+1 or -1).
    """
    p, n, uv = _corner_arrays(positions, normals, uvs, faces)
    if flip_v:
        uv = uv * np.array([1, -1], dtype=np.float32)
    nf = p.shape[0] // 3
    if nf == 0:
        return np.zeros((0, 3, 4), np.float32)
    tang, orient = _mikktspace(p, n, uv)
    out = np.empty((nf * 3, 4), np.float32)
    out[:, 3] = np.where(orient, 1.0, -1.0)
    out[:, :3] = _orthonormal(tang, n) if orthonormalize else tang
    return out.reshape(nf, 3, 4)


def _corner_arrays(positions, normals, uvs, faces):
    """float32 per-corner ``(3F, 3)``, ``(3F, 3)``, ``(3F, 2)`` arrays, validated."""
    arrays = []
    for name, a, k in (("positions", positions, 3), ("normals", normals, 3), ("uvs", uvs, 2)):
        a = np.asarray(a)
        if a.dtype.kind not in "fiu":
            raise ValueError(f"{name} must be numeric, got dtype {a.dtype}")
        if faces is None and a.ndim == 3:
            a = a.reshape(-1, a.shape[-1])
        if a.ndim != 2 or a.shape[1] != k:
            raise ValueError(f"{name} must have shape (N, {k}), got {a.shape}")
        arrays.append(a.astype(np.float32, copy=False))
    if faces is None:
        c = arrays[0].shape[0]
        if c % 3 or any(a.shape[0] != c for a in arrays):
            raise ValueError("an unindexed triangle list needs the same number of rows in "
                             f"positions, normals and uvs, a multiple of 3; got "
                             f"{[a.shape[0] for a in arrays]}")
        return [np.ascontiguousarray(a) for a in arrays]
    f = np.asarray(faces)
    if f.dtype.kind not in "iu" or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be integer (F, 3), got {f.dtype} {f.shape}")
    f = f.reshape(-1).astype(np.int64)
    for name, a in zip(("positions", "normals", "uvs"), arrays):
        if f.size and (f.min() < 0 or f.max() >= a.shape[0]):
            raise ValueError(f"faces index outside {name} (0 .. {a.shape[0] - 1})")
    return [np.ascontiguousarray(a[f]) for a in arrays]


def _corner_ids(p, n, uv) -> np.ndarray:
    """int64 ``(C,)``: for each corner, the first corner with exactly equal attributes."""
    key = np.concatenate([p, n, uv], axis=1) + _ZERO  # -0.0 + 0.0 == +0.0
    bits = key.view(np.uint64)  # 8 float32 -> 4 uint64, compared as bits
    order = np.lexsort(bits.T)
    sb = bits[order]
    start = np.ones(len(order), bool)
    start[1:] = (sb[1:] != sb[:-1]).any(axis=1)
    run = np.cumsum(start) - 1
    first = np.full(run[-1] + 1, len(order), np.int64)
    np.minimum.at(first, run, order)
    ids = np.empty(len(order), np.int64)
    ids[order] = first[run]
    nan = np.isnan(key).any(axis=1)
    ids[nan] = np.flatnonzero(nan)
    return ids


def _triangle_derivatives(p, uv):
    """float32 dP/ds, dP/dt, orientation and 'group with anything' of triangles ``(T, 3, k)``.

    The same float32 operations in the same order as mikktspace.c's InitTriInfo.
    """
    t21x = uv[:, 1, 0] - uv[:, 0, 0]
    t21y = uv[:, 1, 1] - uv[:, 0, 1]
    t31x = uv[:, 2, 0] - uv[:, 0, 0]
    t31y = uv[:, 2, 1] - uv[:, 0, 1]
    d1 = p[:, 1] - p[:, 0]
    d2 = p[:, 2] - p[:, 0]
    area = t21x * t31y - t21y * t31x
    os_ = t31y[:, None] * d1 - t21y[:, None] * d2
    ot = (-t31x)[:, None] * d1 + t21x[:, None] * d2
    orient = area > 0
    has_area = np.abs(area) > _FLT_MIN
    sign = np.where(orient, _F32(1), _F32(-1))
    with np.errstate(all="ignore"):
        len_os = np.sqrt(os_[:, 0] * os_[:, 0] + os_[:, 1] * os_[:, 1] + os_[:, 2] * os_[:, 2])
        len_ot = np.sqrt(ot[:, 0] * ot[:, 0] + ot[:, 1] * ot[:, 1] + ot[:, 2] * ot[:, 2])
        vos = np.where((has_area & (len_os > _FLT_MIN))[:, None],
                       (sign / len_os)[:, None] * os_, _ZERO)
        vot = np.where((has_area & (len_ot > _FLT_MIN))[:, None],
                       (sign / len_ot)[:, None] * ot, _ZERO)
        mag_s = np.abs(len_os / np.abs(area))
        mag_t = np.abs(len_ot / np.abs(area))
    good = has_area & (mag_s > _FLT_MIN) & (mag_t > _FLT_MIN)
    return (vos.astype(np.float32), vot.astype(np.float32), orient, ~good)


def _mikktspace(p, n, uv):
    """MikkTSpace's raw per-corner tangent float32 ``(C, 3)`` and orientation bool ``(C,)``."""
    c = p.shape[0]
    ids = _corner_ids(p, n, uv)
    tp = p.reshape(-1, 3, 3)
    degen = ((tp[:, 0] == tp[:, 1]).all(1) | (tp[:, 0] == tp[:, 2]).all(1)
             | (tp[:, 1] == tp[:, 2]).all(1))
    good = np.flatnonzero(~degen)
    corners = (good[:, None] * 3 + np.arange(3)).reshape(-1)  # healthy corners, in order
    gids = ids[corners].reshape(-1, 3)

    tang = np.zeros((c, 3), np.float32)
    tang[:, 0] = 1.0  # MikkTSpace's default frame, orientation false
    orient_out = np.zeros(c, bool)
    if len(good):
        vos, vot, orient, gwa = _triangle_derivatives(tp[good], uv.reshape(-1, 3, 2)[good])
        nb = _neighbours(gids)
        assigned, gfaces, goff, grep, gorient = _build_groups(gids, gwa, orient, nb)
        gp = p[corners].reshape(-1, 3, 3)
        gn = n[corners].reshape(-1, 3, 3)
        t_good = tang[corners].reshape(-1, 3, 3)
        o_good = orient_out[corners].reshape(-1, 3)
        _group_tspaces(gids, gp, gn, vos, vot, gwa, assigned, gfaces, goff, grep, gorient,
                       _THRES_COS, t_good, o_good)
        tang[corners] = t_good.reshape(-1, 3)
        orient_out[corners] = o_good.reshape(-1)
        if len(good) < len(degen):
            # Degenerate triangles copy from the first healthy corner identified with theirs.
            bad = np.flatnonzero(np.repeat(degen, 3))
            first = np.full(c, c, np.int64)
            np.minimum.at(first, ids[corners], corners)
            src = first[ids[bad]]
            hit = src < c
            tang[bad[hit]] = tang[src[hit]]
            orient_out[bad[hit]] = orient_out[src[hit]]
    return tang, orient_out


def _neighbours(ids) -> np.ndarray:
    """int64 ``(T, 3)``: the triangle across edge i (corner i to i+1), or -1.

    Pairs edges as mikktspace.c's BuildNeighborsFast does: sorted by (min id, max id,
    triangle), each unpaired edge takes the first later unpaired edge of opposite winding.
    """
    a = ids.reshape(-1)
    b = ids[:, [1, 2, 0]].reshape(-1)
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    order = np.lexsort((np.arange(len(a)), hi, lo))
    return _pair_edges(ids, lo, hi, order)


@njit(cache=True)
def _pair_edges(ids, lo, hi, order):
    nt = ids.shape[0]
    ne = nt * 3
    nb = np.full((nt, 3), -1, np.int64)
    for k in range(ne):
        e = order[k]
        f = e // 3
        i = e % 3
        if nb[f, i] != -1:
            continue
        a0 = ids[f, i]
        a1 = ids[f, (i + 1) % 3]
        j = k + 1
        while j < ne and lo[order[j]] == lo[e] and hi[order[j]] == hi[e]:
            e2 = order[j]
            t = e2 // 3
            m = e2 % 3
            if ids[t, m] == a1 and ids[t, (m + 1) % 3] == a0 and nb[t, m] == -1:
                nb[f, i] = t
                nb[t, m] = f
                break
            j += 1
    return nb


@njit(cache=True)
def _build_groups(ids, gwa, orient, nb):
    """mikktspace.c's Build4RuleGroups with AssignRecur as an explicit depth-first stack.

    Returns assigned group per corner ``(T, 3)`` (-1: none), the groups' triangles
    (``gfaces[goff[g]:goff[g+1]]`` in insertion order), representative ids and orientations.
    ``orient`` is updated for 'group with anything' triangles.
    """
    nt = ids.shape[0]
    assigned = np.full((nt, 3), -1, np.int64)
    gfaces = np.empty(nt * 3, np.int64)
    goff = np.zeros(nt * 3 + 1, np.int64)
    grep = np.empty(nt * 3, np.int64)
    gorient = np.empty(nt * 3, np.bool_)
    stack = np.empty(nt * 2 + 2, np.int64)
    ng = 0
    count = 0
    for f in range(nt):
        if gwa[f]:
            continue
        for i in range(3):
            if assigned[f, i] != -1:
                continue
            g = ng
            ng += 1
            rep = ids[f, i]
            grep[g] = rep
            gorient[g] = orient[f]
            gfaces[count] = f
            count += 1
            assigned[f, i] = g
            sp = 0
            if nb[f, (i + 2) % 3] >= 0:
                stack[sp] = nb[f, (i + 2) % 3]
                sp += 1
            if nb[f, i] >= 0:
                stack[sp] = nb[f, i]
                sp += 1
            while sp > 0:
                sp -= 1
                t = stack[sp]
                k = 0 if ids[t, 0] == rep else (1 if ids[t, 1] == rep else 2)
                if assigned[t, k] != -1:
                    continue
                if gwa[t] and assigned[t, 0] == -1 and assigned[t, 1] == -1 \
                        and assigned[t, 2] == -1:
                    orient[t] = gorient[g]  # the first group to reach it decides
                if orient[t] != gorient[g]:
                    continue
                gfaces[count] = t
                count += 1
                assigned[t, k] = g
                if nb[t, (k + 2) % 3] >= 0:
                    stack[sp] = nb[t, (k + 2) % 3]
                    sp += 1
                if nb[t, k] >= 0:
                    stack[sp] = nb[t, k]
                    sp += 1
            goff[g + 1] = count
    return assigned, gfaces, goff[:ng + 1], grep[:ng], gorient[:ng]


@njit(cache=True, inline="always")
def _project3(x, y, z, nx, ny, nz):
    """``v - n (n.v)``, normalized unless every component is within FLT_MIN of zero."""
    d = nx * x + ny * y + nz * z
    x = x - d * nx
    y = y - d * ny
    z = z - d * nz
    if abs(x) > _FLT_MIN or abs(y) > _FLT_MIN or abs(z) > _FLT_MIN:
        s = np.float32(1.0) / np.float32(math.sqrt(x * x + y * y + z * z))
        return s * x, s * y, s * z
    return x, y, z


@njit(cache=True, inline="always")
def _project_unit(v, n):
    return _project3(v[0], v[1], v[2], n[0], n[1], n[2])


@njit(cache=True)
def _group_tspaces(ids, p, n, vos, vot, gwa, assigned, gfaces, goff, grep, gorient,
                   thres_cos, tang, orient_out):
    """mikktspace.c's GenerateTSpaces and EvalTspace; writes ``tang`` and ``orient_out``."""
    ng = grep.shape[0]
    mmax = 1
    for g in range(ng):
        mmax = max(mmax, goff[g + 1] - goff[g])
    corner = np.empty(mmax, np.int64)
    ps = np.empty((mmax, 3), np.float32)
    pt = np.empty((mmax, 3), np.float32)
    members = np.empty(mmax, np.int64)
    sub_members = np.empty(mmax * 4, np.int64)
    sub_off = np.zeros(mmax + 1, np.int64)
    sub_t = np.empty((mmax, 3), np.float32)
    for g in range(ng):
        a = goff[g]
        m = goff[g + 1] - a
        faces = gfaces[a:a + m]
        for q in range(m):
            f = faces[q]
            corner[q] = 0 if assigned[f, 0] == g else (1 if assigned[f, 1] == g else 2)
        nrm = n[faces[0], corner[0]]  # identical at every corner of the group
        for q in range(m):
            ps[q, 0], ps[q, 1], ps[q, 2] = _project_unit(vos[faces[q]], nrm)
            pt[q, 0], pt[q, 1], pt[q, 2] = _project_unit(vot[faces[q]], nrm)
        nsub = 0
        members = np.empty(m, np.int64)
        for q in range(m):
            f = faces[q]
            cnt = 0
            for r in range(m):
                t = faces[r]
                cos_s = ps[q, 0] * ps[r, 0] + ps[q, 1] * ps[r, 1] + ps[q, 2] * ps[r, 2]
                cos_t = pt[q, 0] * pt[r, 0] + pt[q, 1] * pt[r, 1] + pt[q, 2] * pt[r, 2]
                if gwa[f] or gwa[t] or f == t or (cos_s > thres_cos and cos_t > thres_cos):
                    members[cnt] = t
                    cnt += 1
            mem = members[:cnt]
            if cnt > 1:
                mem.sort()
            found = -1
            for s in range(nsub):
                lo = sub_off[s]
                if sub_off[s + 1] - lo == cnt and np.all(sub_members[lo:lo + cnt] == mem):
                    found = s
                    break
            if found < 0:
                found = nsub
                lo = sub_off[nsub]
                if lo + cnt > sub_members.shape[0]:
                    grown = np.empty(max(2 * sub_members.shape[0], lo + cnt), np.int64)
                    grown[:lo] = sub_members[:lo]
                    sub_members = grown
                sub_members[lo:lo + cnt] = mem
                sub_off[nsub + 1] = lo + cnt
                sub_t[nsub, 0], sub_t[nsub, 1], sub_t[nsub, 2] = _eval_tspace(
                    mem, ids, p, vos, gwa, grep[g], nrm)
                nsub += 1
            tang[f, corner[q]] = sub_t[found]
            orient_out[f, corner[q]] = gorient[g]


@njit(cache=True)
def _eval_tspace(mem, ids, p, vos, gwa, rep, nrm):
    """Angle-weighted sum of the members' projected dP/ds at corner ``rep``, normalized."""
    sx = np.float32(0.0)
    sy = np.float32(0.0)
    sz = np.float32(0.0)
    for f in mem:
        if gwa[f]:
            continue
        i = 0 if ids[f, 0] == rep else (1 if ids[f, 1] == rep else 2)
        ox, oy, oz = _project_unit(vos[f], nrm)
        p0 = p[f, (i + 2) % 3]
        p1 = p[f, i]
        p2 = p[f, (i + 1) % 3]
        nx, ny, nz = nrm[0], nrm[1], nrm[2]
        v1 = _project3(p0[0] - p1[0], p0[1] - p1[1], p0[2] - p1[2], nx, ny, nz)
        v2 = _project3(p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2], nx, ny, nz)
        c = v1[0] * v2[0] + v1[1] * v2[1] + v1[2] * v2[2]
        c = min(max(c, np.float32(-1.0)), np.float32(1.0))
        w = np.float32(math.acos(c))
        sx += w * ox
        sy += w * oy
        sz += w * oz
    return _project3(sx, sy, sz, _ZERO, _ZERO, _ZERO)


def _orthonormal(t, n) -> np.ndarray:
    """Unit tangents float32 ``(C, 3)`` orthogonal to the normals, whatever the input."""
    t = t.astype(np.float64)
    n = n.astype(np.float64)
    with np.errstate(all="ignore"):
        nl = np.linalg.norm(n, axis=1, keepdims=True)
        nh = np.where(np.isfinite(nl) & (nl > 1e-30), n / nl, 0.0)
        nh = np.where(np.isfinite(nh), nh, 0.0)
        out = _reject(t, nh)
        bad = ~np.isfinite(out).all(axis=1)
        if bad.any():
            axis = np.eye(3)[np.argmin(np.abs(nh[bad]), axis=1)]
            out[bad] = _reject(axis, nh[bad])
    return out.astype(np.float32)


def _reject(v, nh):
    """``v`` minus its component along unit ``nh``, normalized; NaN rows where it vanishes."""
    r = v - nh * np.sum(v * nh, axis=1, keepdims=True)
    length = np.linalg.norm(r, axis=1, keepdims=True)
    return np.where(length > 1e-6 * np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30),
                    r / length, np.nan)


class Welded(NamedTuple):
    """An indexed vertex buffer made from per-corner attributes."""

    faces: np.ndarray      # uint32 (F, 3): vertex indices
    vertices: dict         # name -> (V, ...) array, dtype kept
    corner: np.ndarray     # int64 (V,): the corner (f * 3 + i) each vertex was taken from


def weld_corners(corner_attributes: Mapping[str, np.ndarray]) -> Welded:
    """Merge corners whose attributes are all bitwise equal into one vertex.

    corner_attributes: name -> array ``(F, 3)`` or ``(F, 3, ...)`` (e.g. positions,
    normals, uvs and the tangents of ``mikktspace_tangents``). A vertex is split only
    where some attribute differs, as glTF needs one tangent per vertex. Vertices are
    numbered in order of first use. To keep attributes that are not passed (skin
    weights, colours) and never merge distinct source vertices, pass the source
    index too, e.g. ``{"source": faces, "tangent": t}``, and gather the rest with
    ``faces.reshape(-1)[welded.corner]``.
    """
    if not corner_attributes:
        raise ValueError("weld_corners needs at least one attribute")
    cols = []
    nf = None
    for name, a in corner_attributes.items():
        a = np.asarray(a)
        if a.ndim < 2 or a.shape[1] != 3 or (nf is not None and a.shape[0] != nf):
            raise ValueError(f"{name} must have shape (F, 3, ...) with the same F as the "
                             f"others, got {a.shape}")
        nf = a.shape[0]
        raw = np.ascontiguousarray(a).reshape(nf * 3, -1)
        cols.append(raw.view(np.uint8).reshape(nf * 3, -1))
    key = np.ascontiguousarray(np.concatenate(cols, axis=1))
    void = key.view(np.dtype((np.void, key.shape[1]))).reshape(-1)
    _, first, inverse = np.unique(void, return_index=True, return_inverse=True)
    # number vertices in order of first use
    rank = np.empty(len(first), np.int64)
    by_first = np.argsort(first)
    rank[by_first] = np.arange(len(first))
    corner = first[by_first]
    faces = rank[inverse.reshape(-1)].reshape(nf, 3).astype(np.uint32)
    vertices = {name: np.asarray(a).reshape((nf * 3,) + np.asarray(a).shape[2:])[corner]
                for name, a in corner_attributes.items()}
    return Welded(faces, vertices, corner)

"""A port of mikktspace.c's ``genTangSpaceDefault`` for triangles, to numpy and numba.

Follows the reference (Morten S. Mikkelsen, zlib licence; not copied here) step by step,
with the same float32 operations in the same order where a decision depends on them:

1. Welding (GenerateSharedVerticesIndexList): corners with equal position, normal and uv
   (float ``==``: ``-0 == +0``, NaN never equal) share the index of the corner that its
   hash grid and kd-split meet first.
2. Triangles with two equal corner positions are degenerate: left out, then each of their
   corners copies the frame of the first healthy corner with its welded index
   (DegenEpilogue), else keeps the default frame (1, 0, 0) with orientation false.
3. InitTriInfo: per triangle dP/ds and dP/dt (eqs. 18-19 of the thesis), the sign of the
   uv area (orientation), "group with anything" when the uv area or a derivative is zero.
4. BuildNeighborsFast: triangles sharing an edge with opposite winding are neighbours,
   found through its seeded quicksort of edges (whose last runs stay unsorted).
5. Build4RuleGroups: around each corner, the neighbours of equal orientation form a group
   (uv seams and mirrored islands split groups); "group with anything" triangles take the
   orientation of the first group that reaches them (the one order dependency).
6. GenerateTSpaces/EvalTspace: a group's tangent is the angle-weighted sum of its members'
   dP/ds projected onto the plane of the corner normal, normalized.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels import CACHE, run
from .topology import corner_ids, neighbours

INTERPRET_CORNERS = 1500  # up to 500 triangles run interpreted (about 0.1 s) on a cold start

_F32 = np.float32
_ZERO = np.float32(0.0)
_FLT_MIN = np.float32(np.finfo(np.float32).tiny)
# genTangSpaceDefault: cos(180 deg) computed as mikktspace.c does, in float.
_THRES_COS = np.float32(math.cos(np.float32(np.float32(180.0) * np.float32(math.pi))
                                  / np.float32(180.0)))


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


def mikktspace(p, n, uv, interpret: bool | None = None):
    """MikkTSpace's per-corner tangent float32 ``(C, 3)`` and orientation bool ``(C,)``.

    p, n: float32 ``(C, 3)``; uv: float32 ``(C, 2)``; C = 3 * triangles, corner order.
    interpret: run the kernels' Python source rather than compiling them (the same
    results); by default for meshes of at most ``INTERPRET_CORNERS`` corners, where
    that is quicker than a first run's compile (about 10 s on two cores).
    """
    c = p.shape[0]
    if interpret is None:
        interpret = c <= INTERPRET_CORNERS
    ids = corner_ids(p, n, uv, interpret)
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
        nb = run(neighbours, gids, interpret=interpret)
        assigned, gfaces, goff, grep, gorient = run(_build_groups, gids, gwa, orient, nb,
                                                    interpret=interpret)
        gp = p[corners].reshape(-1, 3, 3)
        gn = n[corners].reshape(-1, 3, 3)
        t_good = tang[corners].reshape(-1, 3, 3)
        o_good = orient_out[corners].reshape(-1, 3)
        run(_group_tspaces, gids, gp, gn, vos, vot, gwa, assigned, gfaces, goff, grep, gorient,
            _THRES_COS, t_good, o_good, interpret=interpret)
        tang[corners] = t_good.reshape(-1, 3)
        orient_out[corners] = o_good.reshape(-1)
        if len(good) < len(degen):
            # Degenerate triangles copy from the first healthy corner identified with theirs.
            bad = np.flatnonzero(np.repeat(degen, 3))
            first = np.full(int(ids.max()) + 1, c, np.int64)
            np.minimum.at(first, ids[corners], corners)
            src = first[ids[bad]]
            hit = src < c
            tang[bad[hit]] = tang[src[hit]]
            orient_out[bad[hit]] = orient_out[src[hit]]
    return tang, orient_out


@njit(cache=CACHE, error_model="numpy")
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


@njit(cache=CACHE, inline="always", error_model="numpy")
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


@njit(cache=CACHE, inline="always", error_model="numpy")
def _project_unit(v, n):
    return _project3(v[0], v[1], v[2], n[0], n[1], n[2])


@njit(cache=CACHE, error_model="numpy")
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


@njit(cache=CACHE, error_model="numpy")
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
        w = np.float32(math.acos(np.float64(c)))  # (float) acos(fCos), in double as mikktspace.c
        sx += w * ox
        sy += w * oy
        sz += w * oz
    return _project3(sx, sy, sz, _ZERO, _ZERO, _ZERO)

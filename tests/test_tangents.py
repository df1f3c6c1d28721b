"""MikkTSpace tangents against the reference mikktspace.c, properties, and corner welding."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import mikk_reference
from csm_assets.tangents.frames import mikktspace_tangents, weld_corners

ANGLE_TOL = 1e-3  # radians, orthonormalized frames on MikkTSpace's well-defined corners
RAW_TOL = 1e-4    # any component, unprocessed output on every corner (measured: 1e-5)


@pytest.fixture(scope="session")
def mikk(tmp_path_factory):
    """The reference MikkTSpace, downloaded and compiled once per session (or skipped)."""
    try:
        lib = mikk_reference.build(tmp_path_factory.mktemp("mikktspace"))
    except mikk_reference.Unavailable as e:
        pytest.skip(str(e))
    return mikk_reference.Reference(lib)


# ---------------------------------------------------------------- meshes

def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def uv_sphere(nlat=10, nlon=16):
    """Lat-long sphere, indexed: a uv seam at u = 0/1 (same positions and normals) and
    poles whose rows of equal positions make degenerate triangles."""
    th = np.linspace(0, np.pi, nlat + 1)[:, None]
    ph = np.linspace(0, 2 * np.pi, nlon + 1)[None, :]
    p = np.stack(np.broadcast_arrays(np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph),
                                     np.cos(th)), -1)
    p[:, -1] = p[:, 0]            # the seam: exactly the same positions
    p[0] = (0, 0, 1)
    p[-1] = (0, 0, -1)
    uv = np.stack(np.broadcast_arrays(ph / (2 * np.pi), 1 - th / np.pi), -1)
    idx = np.arange((nlat + 1) * (nlon + 1)).reshape(nlat + 1, nlon + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    p = p.reshape(-1, 3)
    return p, _unit(p), uv.reshape(-1, 2), faces


def cube():
    """Flat-shaded cube, 4 vertices per face, per-face uvs (some faces rotated, one mirrored)."""
    p, n, uv, faces = [], [], [], []
    quad_uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)
    for k, (axis, sign) in enumerate([(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1)]):
        nrm = np.zeros(3)
        nrm[axis] = sign
        u = np.roll(nrm, 1)
        v = np.cross(nrm, u)
        corners = [nrm + su * u + sv * v for su, sv in [(-1, -1), (1, -1), (1, 1), (-1, 1)]]
        fuv = np.roll(quad_uv, k, axis=0)
        if k == 3:
            fuv[:, 0] = 1 - fuv[:, 0]  # mirrored face
        base = len(p)
        p += corners
        n += [nrm] * 4
        uv += list(fuv)
        faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(p), np.array(n), np.array(uv), np.array(faces)


def grid(nx=9, ny=7, x0=-1.0, x1=1.0):
    """Indexed grid over [x0, x1] x [0, 1] in the xy plane, normals +z, uv = (x, y)."""
    x, y = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(0, 1, ny))
    p = np.stack([x, y, np.zeros_like(x)], -1).reshape(-1, 3)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    n = np.tile([0.0, 0.0, 1.0], (len(p), 1))
    return p, n, p[:, :2].copy(), faces


def bumpy(p, faces, amp=0.15):
    """Lift a grid by a smooth bump and give it smooth normals."""
    p = p.copy()
    p[:, 2] = amp * np.sin(3 * p[:, 0]) * np.cos(2 * p[:, 1])
    return p, trimesh.Trimesh(p, faces, process=False).vertex_normals


def mirrored_plane():
    """A bumpy plane whose left half mirrors the right half's uvs (u = |x|): handedness flips
    across x = 0, where the vertices are shared."""
    p, _, _, faces = grid(nx=9, ny=6)  # x = 0 is a column of vertices
    p, n = bumpy(p, faces)
    uv = np.stack([np.abs(p[:, 0]), p[:, 1]], -1)
    return p, n, uv, faces


def character(subdivisions=3):
    """Smooth icosphere with a planar front projection mirrored at x = 0 (like a character
    whose left side reuses the right side's texture)."""
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    p = m.vertices * [0.6, 1.0, 0.4]
    n = trimesh.Trimesh(p, m.faces, process=False).vertex_normals
    uv = np.stack([np.abs(p[:, 0]), 0.5 + 0.5 * p[:, 1]], -1)
    return p, n, uv, m.faces


def torus(n_major=24, n_minor=12):
    """Torus with uv seams in both directions (duplicated vertices, equal positions and
    normals, different uvs) and the uv island scaled unevenly."""
    u = np.linspace(0, 1, n_major + 1)[None, :]
    v = np.linspace(0, 1, n_minor + 1)[:, None]
    a, b = 2 * np.pi * u, 2 * np.pi * v
    ring = np.stack(np.broadcast_arrays(np.cos(a), np.sin(a), 0 * a), -1)
    nrm = np.cos(b)[..., None] * ring + np.sin(b)[..., None] * [0, 0, 1.0]
    nrm[:, -1], nrm[-1] = nrm[:, 0], nrm[0]
    p = ring + 0.3 * nrm
    idx = np.arange((n_minor + 1) * (n_major + 1)).reshape(n_minor + 1, n_major + 1)
    q = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([q[0], q[1], q[2]], -1).reshape(-1, 3),
                            np.stack([q[0], q[2], q[3]], -1).reshape(-1, 3)])
    uv = np.stack(np.broadcast_arrays(3 * u, v), -1)
    return p.reshape(-1, 3), nrm.reshape(-1, 3), uv.reshape(-1, 2), faces


def capsule():
    """trimesh's capsule, uv from a mirrored planar projection onto xz."""
    m = trimesh.creation.capsule(height=1.0, radius=0.3, count=[12, 12])
    uv = np.stack([np.abs(m.vertices[:, 0]), m.vertices[:, 2]], -1)
    return m.vertices, m.vertex_normals, uv, m.faces


def degenerate_grid():
    """A bumpy grid with zero-area triangles (one vertex moved exactly onto a neighbour)
    and zero-uv-area triangles (a vertex given its neighbour's uv), plus one isolated
    zero-area triangle and one isolated zero-uv-area triangle of their own."""
    p, _, uv, faces = grid(nx=8, ny=8, x0=0.0)
    p, n = bumpy(p, faces)
    p[9] = p[10]          # collapses the triangles on edge 9-10 (other attributes differ)
    p[27] = p[35]
    uv[20] = uv[21]       # zero uv area on edge 20-21
    uv[44] = uv[52]
    extra_p = [(2, 2, 0), (2, 2, 0), (3, 2, 0), (4, 4, 0), (5, 4, 0), (4, 5, 0)]
    extra_uv = [(0, 0), (1, 0), (1, 1), (0.5, 0.5), (0.5, 0.5), (0.5, 0.5)]
    base = len(p)
    p = np.concatenate([p, extra_p])
    n = np.concatenate([n, [(0, 0, 1)] * 6])
    uv = np.concatenate([uv, extra_uv])
    faces = np.concatenate([faces, [(base, base + 1, base + 2), (base + 3, base + 4, base + 5)]])
    return p, n, uv, faces


def jittered_grid(seed):
    """A bumpy grid with jittered positions and uvs, random normals noise, some triangles
    wound backwards, triangle order shuffled."""
    rng = np.random.default_rng(seed)
    p, _, uv, faces = grid(nx=12, ny=10)
    p[:, :2] += rng.uniform(-0.03, 0.03, (len(p), 2))
    p, n = bumpy(p, faces, amp=0.3)
    n = _unit(n + rng.normal(0, 0.1, n.shape))
    uv = uv + rng.uniform(-0.02, 0.02, uv.shape)
    flip = rng.random(len(faces)) < 0.05
    faces[flip] = faces[flip][:, ::-1]
    return p, n, uv, faces[rng.permutation(len(faces))]


MESHES = {
    "uv_sphere": uv_sphere, "cube": cube, "mirrored_plane": mirrored_plane,
    "character_icosphere": character, "capsule": capsule, "torus": torus, "degenerate": degenerate_grid,
    "jittered_0": lambda: jittered_grid(0), "jittered_1": lambda: jittered_grid(1),
    "jittered_2": lambda: jittered_grid(2),
}


def corners(p, n, uv, faces):
    """float32 per-corner arrays (what both implementations see)."""
    return tuple(np.asarray(a, np.float32)[faces].reshape(-1, a.shape[1]) for a in (p, n, uv))


def well_defined(ref, n):
    """Corners where MikkTSpace gives a unit tangent in the normal's plane."""
    t = ref.reshape(-1, 4)[:, :3].astype(np.float64)
    n = _unit(n.reshape(-1, 3))
    return (np.abs(np.linalg.norm(t, axis=1) - 1) < 1e-4) & (np.abs(np.sum(t * n, 1)) < 1e-4)


def assert_matches(ours, ref, n):
    """Same handedness and tangents within ANGLE_TOL on MikkTSpace's well-defined corners."""
    ok = well_defined(ref, n)
    o = ours.reshape(-1, 4).astype(np.float64)
    r = ref.reshape(-1, 4).astype(np.float64)
    angle = np.arctan2(np.linalg.norm(np.cross(o[:, :3], r[:, :3]), axis=1),
                       np.sum(o[:, :3] * r[:, :3], 1))
    assert np.all(o[ok, 3] == r[ok, 3]), f"{np.sum(o[ok, 3] != r[ok, 3])} handedness differ"
    assert angle[ok].max(initial=0) < ANGLE_TOL, f"max angle {angle[ok].max()}"
    return ok


# ---------------------------------------------------------------- against the reference

@pytest.mark.parametrize("name", sorted(MESHES))
def test_matches_reference_mikktspace(mikk, name):
    p, n, uv, faces = MESHES[name]()
    cp, cn, cuv = corners(p, n, uv, faces)
    ref = mikk.tangents(cp, cn, cuv)
    raw = mikktspace_tangents(p, n, uv, faces, orthonormalize=False)
    # unprocessed: every corner, including MikkTSpace's zero and default frames
    assert np.abs(raw - ref).max() < RAW_TOL
    ours = mikktspace_tangents(p, n, uv, faces)
    ok = assert_matches(ours, ref, cn)
    # only corners of degenerate triangles may lack a frame
    tri = cp.reshape(-1, 3, 3)
    degen = np.zeros(len(tri), bool)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        degen |= (tri[:, i] == tri[:, j]).all(1)
    uvt = cuv.reshape(-1, 3, 2).astype(np.float64)
    e1, e2 = uvt[:, 1] - uvt[:, 0], uvt[:, 2] - uvt[:, 0]
    degen |= e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] == 0
    assert ok.reshape(-1, 3)[~degen].all()
    if name != "degenerate":
        assert ok.mean() > 0.9


def test_degenerate_mesh_has_both_kinds(mikk):
    """The degenerate fixture really holds zero-area and zero-uv-area triangles, and
    MikkTSpace leaves the isolated ones at its default frame (1, 0, 0), sign -1."""
    p, n, uv, faces = degenerate_grid()
    cp, cn, cuv = corners(p, n, uv, faces)
    ref = mikk.tangents(cp, cn, cuv)
    np.testing.assert_array_equal(ref[-2:].reshape(-1, 4), [[1, 0, 0, -1]] * 6)
    ours = mikktspace_tangents(p, n, uv, faces, orthonormalize=False)
    np.testing.assert_array_equal(ours[-2:].reshape(-1, 4), [[1, 0, 0, -1]] * 6)
    fixed = mikktspace_tangents(p, n, uv, faces)[-2:].reshape(-1, 4)
    assert np.allclose(np.abs(fixed[:, :3] @ [0, 0, 1]), 0) and np.all(fixed[:, 3] == -1)


def test_flip_v_is_mikktspace_of_one_minus_v(mikk):
    """flip_v=True (glTF uvs) gives MikkTSpace's frames of (u, 1 - v)."""
    for make in (uv_sphere, character, mirrored_plane):
        p, n, uv, faces = make()
        cp, cn, cuv = corners(p, n, uv, faces)
        cuv[:, 1] = 1 - cuv[:, 1]
        ref = mikk.tangents(cp, cn, cuv)
        ours = mikktspace_tangents(p, n, uv, faces, flip_v=True)
        assert assert_matches(ours, ref, cn).mean() > 0.9


def test_flip_v_bitangent_points_up_the_image():
    """glTF: v grows downward; the normal map's +Y (green) is up the image, so with
    flip_v the bitangent cross(n, t) * w must point towards decreasing v."""
    p = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    n = np.tile([0, 0, 1.0], (4, 1))
    uv_gltf = np.stack([p[:, 0], 1 - p[:, 1]], -1)  # image top at y = 1
    faces = np.array([(0, 1, 2), (0, 2, 3)])
    t = mikktspace_tangents(p, n, uv_gltf, faces, flip_v=True).reshape(-1, 4)
    b = np.cross(n[faces].reshape(-1, 3), t[:, :3]) * t[:, 3:]
    np.testing.assert_allclose(t[:, :3], np.tile([1, 0, 0], (6, 1)), atol=1e-6)
    np.testing.assert_allclose(b, np.tile([0, 1, 0], (6, 1)), atol=1e-6)  # up: +y
    t0 = mikktspace_tangents(p, n, uv_gltf, faces).reshape(-1, 4)
    np.testing.assert_array_equal(t0[:, 3], -t[:, 3])


def test_flip_v_only_flips_handedness():
    """Negating v is exact, so where no triangle has a zero uv area (those take the first
    group's orientation), flip_v gives bit-identical tangents and every w negated."""
    for make in (uv_sphere, torus, mirrored_plane):
        p, n, uv, faces = make()
        a = mikktspace_tangents(p, n, uv, faces)
        b = mikktspace_tangents(p, n, uv, faces, flip_v=True)
        tri = p[faces]
        healthy = ~((tri[:, 0] == tri[:, 1]).all(1) | (tri[:, 1] == tri[:, 2]).all(1)
                    | (tri[:, 0] == tri[:, 2]).all(1))
        np.testing.assert_array_equal(a[healthy, :, :3], b[healthy, :, :3])
        np.testing.assert_array_equal(a[healthy, :, 3], -b[healthy, :, 3])


_small = st.sampled_from([0.0, 0.5, 1.0, 2.0, -1.0])


@settings(max_examples=40)
@given(st.data())
def test_random_tangled_meshes_match_reference(mikk, data):
    """Few vertices on a coarse lattice, random triangles: shared and repeated corners,
    non-manifold edges, both windings, degenerate and zero-uv triangles everywhere."""
    nv = data.draw(st.integers(3, 10))
    nf = data.draw(st.integers(1, 30))
    p = data.draw(hnp.arrays(np.float64, (nv, 3), elements=_small))
    uv = data.draw(hnp.arrays(np.float64, (nv, 2), elements=_small))
    n = _unit(data.draw(hnp.arrays(np.float64, (nv, 3), elements=_small)) + [0, 0, 3.5])
    faces = data.draw(hnp.arrays(np.int64, (nf, 3), elements=st.integers(0, nv - 1)))
    cp, cn, cuv = corners(p, n, uv, faces)
    ref = mikk.tangents(cp, cn, cuv)
    raw = mikktspace_tangents(p, n, uv, faces, orthonormalize=False)
    assert np.abs(raw - ref).max() < RAW_TOL


def test_seeded_tangled_meshes_match_reference(mikk):
    """Bigger tangles than hypothesis draws: dozens of vertices on a few random values,
    up to 200 random triangles. Here which non-manifold edges pair up depends on the
    order mikktspace.c's quicksort leaves the last run of edges in: a fully sorted
    edge list differs from the reference on about one mesh in ten."""
    rng = np.random.default_rng(1)
    for _ in range(80):
        nv, nf, k = rng.integers(3, 60), rng.integers(1, 200), rng.integers(2, 8)
        vals = rng.normal(size=k)
        p = vals[rng.integers(0, k, (nv, 3))]
        uv = vals[rng.integers(0, k, (nv, 2))]
        n = _unit(rng.normal(size=(nv, 3)))
        faces = rng.integers(0, nv, (nf, 3))
        ref = mikk.tangents(*corners(p, n, uv, faces))
        raw = mikktspace_tangents(p, n, uv, faces, orthonormalize=False)
        assert np.abs(raw - ref).max() < RAW_TOL


# ---------------------------------------------------------------- properties

def check_frames(t, n):
    """Unit, finite, orthogonal to the (normalized, finite, non-zero) normal, w = +-1."""
    t = t.reshape(-1, 4).astype(np.float64)
    assert np.isfinite(t).all()
    assert np.all(np.abs(t[:, 3]) == 1)
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1, atol=1e-5)
    n = np.asarray(n, np.float64).reshape(-1, 3)
    with np.errstate(all="ignore"):
        ln = np.linalg.norm(n, axis=1)
        ok = np.isfinite(ln) & (ln > 1e-12) & (ln < 1e30)
        nh = n[ok] / ln[ok, None]
    assert np.abs(np.sum(t[ok, :3] * nh, 1)).max(initial=0) < 1e-5


@pytest.mark.parametrize("name", sorted(MESHES))
def test_frames_are_orthonormal(name):
    p, n, uv, faces = MESHES[name]()
    check_frames(mikktspace_tangents(p, n, uv, faces), np.asarray(n)[faces])


_any_float = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=40)
@given(st.data())
def test_any_input_gives_unit_orthogonal_frames(data):
    """NaN, infinities, huge and tiny values, zero normals: never a NaN out."""
    nf = data.draw(st.integers(1, 6))
    elems = st.one_of(_any_float, _small)
    p = data.draw(hnp.arrays(np.float32, (3 * nf, 3), elements=elems))
    n = data.draw(hnp.arrays(np.float32, (3 * nf, 3), elements=elems))
    uv = data.draw(hnp.arrays(np.float32, (3 * nf, 2), elements=elems))
    flip = data.draw(st.booleans())
    with np.errstate(all="ignore"):
        t = mikktspace_tangents(p, n, uv, flip_v=flip)
    assert t.shape == (nf, 3, 4) and t.dtype == np.float32
    check_frames(t, n)


def test_tangent_follows_u_and_handedness_follows_mirroring():
    """A flat grid with u = |x|: the tangent follows increasing u (+x on the right, -x on
    the mirrored left half) and the mirrored half is left-handed (w = -1)."""
    p, n, uv, faces = grid(nx=9, ny=3)
    uv = np.stack([np.abs(p[:, 0]), p[:, 1]], -1)
    t = mikktspace_tangents(p, n, uv, faces)
    x = p[faces][..., 0].mean(axis=1)  # triangle centres
    right, left = x > 0, x < 0
    np.testing.assert_allclose(t[right, :, :3], np.broadcast_to([1, 0, 0], t[right, :, :3].shape),
                               atol=1e-6)
    np.testing.assert_allclose(t[left, :, :3], np.broadcast_to([-1, 0, 0], t[left, :, :3].shape),
                               atol=1e-6)
    assert np.all(t[right, :, 3] == 1) and np.all(t[left, :, 3] == -1)


def test_triangle_order_and_rotation_do_not_matter():
    """MikkTSpace is order independent where no triangle has a zero uv area (those join
    the first group that reaches them)."""
    p, n, uv, faces = mirrored_plane()
    e = uv[faces[:, 1:]] - uv[faces[:, :1]]
    assert np.all(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0] != 0)
    t = mikktspace_tangents(p, n, uv, faces)
    rng = np.random.default_rng(3)
    perm = rng.permutation(len(faces))
    rot = rng.integers(0, 3, len(faces))
    f2 = np.array([np.roll(f, -r) for f, r in zip(faces[perm], rot)])
    t2 = mikktspace_tangents(p, n, uv, f2)
    back = np.array([np.roll(tt, r, axis=0) for tt, r in zip(t2, rot)])
    np.testing.assert_allclose(back, t[perm], atol=1e-5)


def test_unindexed_and_indexed_agree():
    p, n, uv, faces = uv_sphere()
    a = mikktspace_tangents(p, n, uv, faces)
    b = mikktspace_tangents(p[faces], n[faces], uv[faces])
    np.testing.assert_array_equal(a, b)


def test_empty_and_bad_input():
    empty = mikktspace_tangents(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)))
    assert empty.shape == (0, 3, 4)
    with pytest.raises(ValueError, match="multiple of 3"):
        mikktspace_tangents(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="uvs must have shape"):
        mikktspace_tangents(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="faces index outside"):
        mikktspace_tangents(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)), [[0, 1, 3]])
    with pytest.raises(ValueError, match="faces must be integer"):
        mikktspace_tangents(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)), [[0.0, 1, 2]])


# ---------------------------------------------------------------- welding

def slow_weld(attrs):
    """Obviously correct: a dict from the bytes of every attribute to the first corner."""
    arrays = [np.ascontiguousarray(a).reshape(len(a) * 3, -1) for a in attrs.values()]
    seen, faces, corner = {}, [], []
    for c in range(len(arrays[0])):
        key = b"".join(a[c].tobytes() for a in arrays)
        if key not in seen:
            seen[key] = len(corner)
            corner.append(c)
        faces.append(seen[key])
    return np.array(faces).reshape(-1, 3), np.array(corner)


def test_weld_splits_only_where_tangents_differ():
    p, n, uv, faces = mirrored_plane()
    t = mikktspace_tangents(p, n, uv, faces)
    w = weld_corners({"source": faces, "tangent": t})
    ref_faces, ref_corner = slow_weld({"source": faces, "tangent": t})
    np.testing.assert_array_equal(w.faces, ref_faces)
    np.testing.assert_array_equal(w.corner, ref_corner)
    np.testing.assert_array_equal(w.vertices["tangent"][w.faces], t)
    np.testing.assert_array_equal(w.vertices["source"][w.faces], faces)
    # the mirror line (x = 0) holds the only vertices with two frames
    split = np.bincount(w.vertices["source"], minlength=len(p)) > 1
    assert split.any() and np.all(p[split, 0] == 0)
    assert w.faces.dtype == np.uint32


@settings(max_examples=30)
@given(st.data())
def test_weld_against_slow_reference(data):
    nf = data.draw(st.integers(1, 12))
    a = data.draw(hnp.arrays(np.float32, (nf, 3, 2), elements=st.sampled_from([0.0, 1.0, -0.0])))
    b = data.draw(hnp.arrays(np.int64, (nf, 3), elements=st.integers(0, 2)))
    w = weld_corners({"a": a, "b": b})
    ref_faces, ref_corner = slow_weld({"a": a, "b": b})
    np.testing.assert_array_equal(w.faces, ref_faces)
    np.testing.assert_array_equal(w.corner, ref_corner)
    np.testing.assert_array_equal(w.vertices["a"][w.faces], a)


def test_weld_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="same F"):
        weld_corners({"a": np.zeros((2, 3)), "b": np.zeros((3, 3))})
    with pytest.raises(ValueError, match="at least one"):
        weld_corners({})
    with pytest.raises(ValueError, match="numeric"):
        weld_corners({"a": np.zeros((2, 3), object)})


def test_weld_empty():
    w = weld_corners({"t": np.zeros((0, 3, 4), np.float32), "s": np.zeros((0, 3), np.int64)})
    assert w.faces.shape == (0, 3) and w.vertices["t"].shape == (0, 4) and len(w.corner) == 0

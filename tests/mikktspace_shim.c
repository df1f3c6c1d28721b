/* ctypes shim around the reference mikktspace.c (downloaded at test time, never vendored).
 * csm_mikk_tangents: an unindexed triangle list of nf faces (float32 arrays of 3*nf
 * positions, normals (xyz) and uvs (uv)) -> per-corner tangents, out[4*corner] = x y z sign.
 * Returns genTangSpaceDefault's result (1 on success). */
#include "mikktspace.h"

typedef struct {
    int nf;
    const float *pos, *nrm, *uv;
    float *out;
} Mesh;

static const Mesh *mesh(const SMikkTSpaceContext *c) { return (const Mesh *)c->m_pUserData; }
static int num_faces(const SMikkTSpaceContext *c) { return mesh(c)->nf; }
static int num_verts(const SMikkTSpaceContext *c, const int f) { (void)c; (void)f; return 3; }

static void get_position(const SMikkTSpaceContext *c, float o[], const int f, const int v) {
    const float *p = mesh(c)->pos + 3 * (3 * f + v);
    o[0] = p[0]; o[1] = p[1]; o[2] = p[2];
}
static void get_normal(const SMikkTSpaceContext *c, float o[], const int f, const int v) {
    const float *p = mesh(c)->nrm + 3 * (3 * f + v);
    o[0] = p[0]; o[1] = p[1]; o[2] = p[2];
}
static void get_texcoord(const SMikkTSpaceContext *c, float o[], const int f, const int v) {
    const float *p = mesh(c)->uv + 2 * (3 * f + v);
    o[0] = p[0]; o[1] = p[1];
}
static void set_tspace_basic(const SMikkTSpaceContext *c, const float t[], const float sign,
                             const int f, const int v) {
    float *o = mesh(c)->out + 4 * (3 * f + v);
    o[0] = t[0]; o[1] = t[1]; o[2] = t[2]; o[3] = sign;
}

int csm_mikk_tangents(int nf, const float *pos, const float *nrm, const float *uv, float *out) {
    Mesh m = {nf, pos, nrm, uv, out};
    SMikkTSpaceInterface iface = {0};
    SMikkTSpaceContext ctx;
    iface.m_getNumFaces = num_faces;
    iface.m_getNumVerticesOfFace = num_verts;
    iface.m_getPosition = get_position;
    iface.m_getNormal = get_normal;
    iface.m_getTexCoord = get_texcoord;
    iface.m_setTSpaceBasic = set_tspace_basic;
    ctx.m_pInterface = &iface;
    ctx.m_pUserData = &m;
    return genTangSpaceDefault(&ctx);
}

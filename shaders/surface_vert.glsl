// surface_vert.glsl: passes the world position and the tangent frame (GLSL 330 core).
//
// Attributes: in_position, in_normal (unit), in_tangent (glTF TANGENT: xyz the
// unit direction of increasing u, w = +1 or -1 so that the bitangent
// cross(normal, tangent.xyz) * w points up the image, the direction of decreasing
// v, as MikkTSpace on glTF uvs gives it), in_uv (v grows downward, glTF).

in vec3 in_position;
in vec3 in_normal;
in vec4 in_tangent;
in vec2 in_uv;

uniform mat4 model;      // object to world
uniform mat4 view_proj;  // world to clip

out vec3 v_world;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;

void main()
{
    vec4 world = model * vec4(in_position, 1.0);
    mat3 linear = mat3(model);
    v_world = world.xyz;
    v_normal = transpose(inverse(linear)) * in_normal;
    v_tangent = vec4(linear * in_tangent.xyz, in_tangent.w);
    v_uv = in_uv;
    gl_Position = view_proj * world;
}

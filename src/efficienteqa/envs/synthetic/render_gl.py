"""The OpenGL side of the synthetic renderer: the EGL context, the shaders, the vertex layout.

``render.Renderer`` draws with these; they are kept apart from it because they are the fixed
GPU contract (shader sources, uniform names, the interleaved vertex record, the camera -> clip
matrix), which changes rarely and independently of how a scene is batched and drawn.
"""

from __future__ import annotations

import hashlib

import moderngl
import numpy as np

from efficienteqa.envs.synthetic.mesh import MeshPart
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec

NEAR_M = 0.05
FAR_M = 50.0
MAX_LIGHTS = 32
_EGL_FIX = "sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri"

_VERTEX_SHADER = """
#version 330
uniform mat4 u_view_proj;   // world -> clip
uniform mat4 u_view;        // world -> camera (OpenCV axes)
invariant gl_Position;      // the depth pre-pass must produce bit-identical depths
in vec3 in_pos; in vec3 in_nrm; in vec2 in_uv; in vec3 in_col; in float in_emi; in int in_inst;
out vec3 v_world; out vec3 v_nrm; out vec2 v_uv; out vec3 v_col; out float v_emi; out float v_z;
flat out int v_inst;
void main() {
    v_world = in_pos; v_nrm = in_nrm; v_uv = in_uv; v_col = in_col; v_emi = in_emi;
    v_inst = in_inst;
    v_z = (u_view * vec4(in_pos, 1.0)).z;
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
"""

_FRAGMENT_SHADER = """
#version 330
uniform sampler2D u_tex;
uniform bool u_textured;
uniform bool u_ortho;        // top-down view: the viewer is straight above
uniform vec3 u_eye;          // camera centre, world
uniform float u_ambient;
uniform vec3 u_sun_dir;      // unit vector towards the sun, world
uniform float u_sun;
uniform int u_n_lights;
uniform vec3 u_light_pos[MAX_LIGHTS];
uniform vec3 u_light_col[MAX_LIGHTS];   // colour * intensity
uniform float u_light_inv_r2[MAX_LIGHTS];
in vec3 v_world; in vec3 v_nrm; in vec2 v_uv; in vec3 v_col; in float v_emi; in float v_z;
flat in int v_inst;
layout(location = 0) out vec4 f_rgba;
layout(location = 1) out float f_depth;
layout(location = 2) out int f_inst;
void main() {
    vec4 albedo = vec4(v_col, 1.0);
    if (u_textured) {
        vec4 t = texture(u_tex, v_uv);
#ifdef CUTOUT
        if (t.a < 0.5) discard;
#endif
        albedo.rgb *= t.rgb;
    }
    vec3 to_eye = u_ortho ? vec3(0.0, 0.0, 1.0) : normalize(u_eye - v_world);
    vec3 n = v_nrm;
    if (dot(n, n) < 1e-6) n = cross(dFdx(v_world), dFdy(v_world));
    n = normalize(n);
    if (dot(n, to_eye) < 0.0) n = -n;          // double-sided: face the viewer
    vec3 lin = albedo.rgb * albedo.rgb;        // sRGB-ish -> linear (gamma 2)
    vec3 light = vec3(u_ambient + u_sun * max(dot(n, u_sun_dir), 0.0));
    vec3 spec = vec3(0.0);
    for (int i = 0; i < u_n_lights; ++i) {
        vec3 d = u_light_pos[i] - v_world;
        float d2 = dot(d, d);
        float w = clamp(1.0 - d2 * u_light_inv_r2[i], 0.0, 1.0);
        if (w <= 0.0) continue;
        vec3 l = d * inversesqrt(d2);
        vec3 c = u_light_col[i] * (w * w);
        light += c * max(dot(n, l), 0.0);
        float h = max(dot(n, normalize(l + to_eye)), 0.0);
        h *= h; h *= h; h *= h; h *= h; h *= h;  // h^32 without pow()
        spec += c * h;
    }
    vec3 lit = sqrt(clamp(lin * light + 0.08 * spec, 0.0, 1.0));
    f_rgba = vec4(mix(lit, albedo.rgb, clamp(v_emi, 0.0, 1.0)), 1.0);
    f_depth = v_z;
    f_inst = v_inst + 1;
}
""".replace("MAX_LIGHTS", str(MAX_LIGHTS))

_DEPTH_VERTEX_SHADER = """
#version 330
uniform mat4 u_view_proj;
in vec3 in_pos;
invariant gl_Position;
void main() { gl_Position = u_view_proj * vec4(in_pos, 1.0); }
"""

_DEPTH_FRAGMENT_SHADER = """
#version 330
void main() {}
"""

VERTEX_DTYPE = np.dtype(
    [("pos", "f4", 3), ("nrm", "f4", 3), ("uv", "f4", 2), ("col", "f4", 3), ("emi", "f4"),
     ("inst", "i4")]
)
ATTRIBUTES = ("in_pos", "in_nrm", "in_uv", "in_col", "in_emi", "in_inst")


def projection_matrix(camera: CameraSpec, near: float = NEAR_M, far: float = FAR_M) -> np.ndarray:
    """4x4 camera (OpenCV axes) -> clip matrix from the intrinsics K.

    Pixel (u, v) of K (u right, v down, centres at +0.5) lands on window pixel (u, v), so the
    read-back rows are top-first. NDC z is -1 at ``near`` and +1 at ``far``.
    """
    k = camera.intrinsics
    w, h = camera.width, camera.height
    return np.array([
        [2 * k[0, 0] / w, 0.0, 2 * k[0, 2] / w - 1.0, 0.0],
        [0.0, 2 * k[1, 1] / h, 2 * k[1, 2] / h - 1.0, 0.0],
        [0.0, 0.0, (far + near) / (far - near), -2 * far * near / (far - near)],
        [0.0, 0.0, 1.0, 0.0],
    ])


def create_context() -> moderngl.Context:
    """A headless EGL context, or an error naming the packages that provide one."""
    try:
        # moderngl-stubs 5.13 annotates **settings as Dict[str, Any]; the values are plain
        # settings (backend="egl" is the documented headless call)
        return moderngl.create_standalone_context(backend="egl")  # type: ignore[arg-type]
    except Exception as exc:  # missing libEGL / Mesa drivers, no device
        raise EfficientEQAError(f"cannot create an off-screen EGL OpenGL context: {exc}",
                                fix=_EGL_FIX) from exc


def texture_key(texture: np.ndarray) -> str:
    """Equal for equal images: parts sharing a texture share one GL texture and batch."""
    return f"{texture.shape}:{hashlib.blake2b(np.ascontiguousarray(texture).data).hexdigest()}"


def uniform(program: moderngl.Program, name: str) -> moderngl.Uniform:
    """The program's uniform ``name`` (not a block, attribute or varying of that name)."""
    member = program[name]
    if not isinstance(member, moderngl.Uniform):
        raise TypeError(f"{name!r} is a {type(member).__name__}, not a uniform")
    return member


def part_vertices(part: MeshPart, colour: np.ndarray) -> np.ndarray:
    """The part's vertices as ``VERTEX_DTYPE`` records, painted ``colour``."""
    n = len(part.positions)
    v = np.empty(n, VERTEX_DTYPE)
    v["pos"] = part.positions
    v["nrm"] = part.normals if part.normals is not None and len(part.normals) == n else 0.0
    v["uv"] = part.uvs if part.uvs is not None and part.texture is not None else 0.0
    v["col"] = colour
    v["emi"] = part.emissive
    v["inst"] = part.instance_id
    return v


def compile_programs(ctx: moderngl.Context) -> tuple[dict[bool, moderngl.Program], moderngl.Program]:
    """The shading programs ({cutout: program}; cutout ones discard texels of alpha < 0.5) and
    the depth-only program of the pre-pass."""
    programs = {
        cutout: ctx.program(
            vertex_shader=_VERTEX_SHADER,
            fragment_shader=_FRAGMENT_SHADER.replace(
                "#version 330", "#version 330\n#define CUTOUT" if cutout else "#version 330"),
        )
        for cutout in (False, True)
    }
    depth = ctx.program(vertex_shader=_DEPTH_VERTEX_SHADER, fragment_shader=_DEPTH_FRAGMENT_SHADER)
    return programs, depth

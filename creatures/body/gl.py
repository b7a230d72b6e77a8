"""Instanced meshes drawn offscreen with plain OpenGL: the GL half of :mod:`creatures.body.render`.

pyrender drew the bodies at ~50 frames/s for one body at 640×480 and ~10 for three on this
machine's software GL (llvmpipe): a new mesh node per frame, a 4× multisampled framebuffer
resolved and read back with its depth on every frame, and Python calls per node. Here each
mesh (sphere, cylinder) is uploaded once; every instance's transform and material is a row of
one float32 array uploaded with one ``glBufferSubData`` per frame; a frame is two instanced
draw calls into a single-sampled framebuffer and one colour read into a buffer kept from
frame to frame (depth only when asked). The shading is pyrender's own metallic-roughness
model for one directional light and ambient light (``pyrender/shaders/mesh.frag``, the branch
for untextured materials, ported term for term), so frames match the old renderer's except
along edges, which it antialiased (``tests/test_render.py`` states and checks the tolerance).

pyrender still provides the offscreen context (its EGL or OSMesa platform): it is what picks
an EGL device and works around driver quirks, and the platform probe in
:func:`creatures.body.render.gl_platform` already relies on it.
"""

from __future__ import annotations

import ctypes

import numpy as np
from OpenGL import GL

INSTANCE_INPUTS = """
#version 330 core
layout(location = 0) in vec3 position;
layout(location = 2) in mat4 inst_m;
layout(location = 6) in vec3 inst_base;
layout(location = 7) in vec3 inst_emissive;
layout(location = 8) in vec2 inst_roughness_metallic;
uniform mat4 V;
uniform mat4 P;
flat out vec3 base_color;
flat out vec3 emissive;
flat out vec2 roughness_metallic;
"""
"""What both vertex shaders read of an instance (its row, :data:`ROW`) and pass on flat."""

VERTEX_SHADER = INSTANCE_INPUTS + """
layout(location = 1) in vec3 normal;
out vec3 frag_position;
out vec3 frag_normal;
void main()
{
    gl_Position = P * V * inst_m * vec4(position, 1);
    frag_position = vec3(inst_m * vec4(position, 1.0));
    // transpose(inverse(M)) as pyrender has it, for a transform whose columns are orthogonal
    // (a rotation times a scale, as every instance here is): each column over its length².
    mat3 M = mat3(inst_m);
    frag_normal = normalize(M * (normal / vec3(dot(M[0], M[0]), dot(M[1], M[1]), dot(M[2], M[2]))));
    base_color = inst_base;
    emissive = inst_emissive;
    roughness_metallic = inst_roughness_metallic;
}
"""

SPHERE_VERTEX_SHADER = INSTANCE_INPUTS + """
uniform vec3 cam_pos;
out vec3 frag_position;
flat out vec3 centre;
flat out float radius;
void main()
{
    // A square facing the camera through the sphere's centre, wide enough to hold its outline
    // from anywhere in the frustum (the tangent cone's width there, doubled for obliquity).
    centre = inst_m[3].xyz;
    radius = inst_m[0][0];
    vec3 right = vec3(V[0][0], V[1][0], V[2][0]);
    vec3 up = vec3(V[0][1], V[1][1], V[2][1]);
    float d = length(centre - cam_pos);
    float half_width = 2.0 * radius * d / sqrt(max(d * d - radius * radius, 1e-12));
    frag_position = centre + half_width * (position.x * right + position.y * up);
    gl_Position = P * V * vec4(frag_position, 1.0);
    base_color = inst_base;
    emissive = inst_emissive;
    roughness_metallic = inst_roughness_metallic;
}
"""

SHADING = """
#version 330 core
const float PI = 3.141592653589793;
const float min_roughness = 0.04;
flat in vec3 base_color;
flat in vec3 emissive;
flat in vec2 roughness_metallic;
uniform vec3 cam_pos;
uniform vec3 light_direction;
uniform vec3 light_radiance;
uniform vec3 ambient_light;
out vec4 frag_color;
vec4 shade(vec3 position, vec3 normal)
{
    float roughness = clamp(roughness_metallic.x, min_roughness, 1.0);
    float metallic = clamp(roughness_metallic.y, 0.0, 1.0);
    vec3 c_diff = mix(vec3(0.0), base_color * (1 - min_roughness), 1.0 - metallic);
    vec3 f0 = mix(vec3(min_roughness), base_color, metallic);
    vec3 n = normalize(normal);
    vec3 v = normalize(cam_pos - position);
    vec3 l = normalize(-1.0 * light_direction);
    vec3 h = normalize(l + v);
    float nl = clamp(dot(n, l), 0.001, 1.0);
    float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
    float nh = clamp(dot(n, h), 0.0, 1.0);
    float vh = clamp(dot(v, h), 0.0, 1.0);
    vec3 F = f0 + (1.0 - f0) * pow(clamp(1.0 - vh, 0.0, 1.0), 5.0);
    float r = roughness + 1.0;
    float k = r * r / 8.0;
    float G = (nv / (nv * (1.0 - k) + k)) * (nl / (nl * (1.0 - k) + k));
    float a = roughness * roughness;
    float a2 = a * a;
    float denom = (nh * nh * (a2 - 1.0) + 1.0);
    float D = a2 / (PI * denom * denom);
    vec3 diffuse_contrib = (1.0 - F) * c_diff / PI;
    vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);
    vec3 color = nl * light_radiance * (diffuse_contrib + spec_contrib);
    color += base_color * ambient_light;
    color += emissive * emissive;
    return clamp(vec4(pow(color, vec3(1.0 / 2.2)), 1.0), 0.0, 1.0);
}
"""
"""pyrender's metallic-roughness shading of one point, shared by both fragment shaders."""

FRAGMENT_SHADER = SHADING + """
in vec3 frag_position;
in vec3 frag_normal;
void main()
{
    frag_color = shade(frag_position, frag_normal);
}
"""

SPHERE_FRAGMENT_SHADER = SHADING + """
in vec3 frag_position;
flat in vec3 centre;
flat in float radius;
uniform mat4 V;
uniform mat4 P;
void main()
{
    // The camera's ray through this pixel meets the sphere (or misses: nothing drawn here).
    vec3 ray = normalize(frag_position - cam_pos);
    vec3 from_centre = cam_pos - centre;
    float b = dot(from_centre, ray);
    float h = b * b - dot(from_centre, from_centre) + radius * radius;
    if (h < 0.0) discard;
    vec3 hit = cam_pos + (-b - sqrt(h)) * ray;
    vec4 clip = P * V * vec4(hit, 1.0);
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
    frag_color = shade(hit, (hit - centre) / radius);
}
"""

SQUARE = (np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]]),
          np.array([[0.0, 0.0, 1.0]] * 4), np.array([[0, 1, 2], [0, 2, 3]]))
"""The mesh of a sphere drawn as an impostor: a square the vertex shader turns to the camera."""


ROW = 24
"""Floats per instance: a column-major 4×4 transform, base colour, emissive colour, roughness,
metallic."""
TRANSFORM, BASE, EMISSIVE, ROUGHNESS, METALLIC = slice(0, 16), slice(16, 19), slice(19, 22), 22, 23


def _compile(source: str, kind: int) -> int:
    shader = GL.glCreateShader(kind)
    GL.glShaderSource(shader, source)
    GL.glCompileShader(shader)
    if not GL.glGetShaderiv(shader, GL.GL_COMPILE_STATUS):
        raise RuntimeError(f"shader did not compile: {GL.glGetShaderInfoLog(shader)!r}")
    return shader


class InstancedMeshes:
    """Meshes drawn many times each from one instance buffer, into an offscreen frame.

    ``meshes`` are ``(positions (V, 3), normals (V, 3), triangles (T, 3))``; mesh ``k`` draws
    ``counts[k]`` instances from rows ``offsets[k]…`` of :attr:`instances` (which the caller
    fills; see :data:`ROW`). The meshes numbered in ``spheres`` are :data:`SQUARE` drawn as
    sphere impostors: each instance a sphere of radius ``transform[0, 0]`` at the transform's
    centre, ray-cast per pixel (exact outline, normal and depth) on a square turned to the
    camera — two triangles where a mesh fine enough to look round took 320, and on llvmpipe it
    is the triangles a frame costs (measured: three bodies at 640×480, 57 joints, 18 → 7 ms of
    CPU a frame at load 10). Must be created with the platform's context current.
    """

    def __init__(self, width: int, height: int, meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                 *, spheres: frozenset[int] = frozenset(), capacity: int = 256, framebuffer: bool = True) -> None:
        self.width, self.height = width, height
        self._spheres = spheres
        self._programs = [self._link(VERTEX_SHADER, FRAGMENT_SHADER),
                          self._link(SPHERE_VERTEX_SHADER, SPHERE_FRAGMENT_SHADER)]
        self._uniforms = [{name: GL.glGetUniformLocation(program, name)
                           for name in ("V", "P", "cam_pos", "light_direction", "light_radiance", "ambient_light")}
                          for program in self._programs]
        self._framebuffer = 0
        self._renderbuffers: list[int] = []
        if framebuffer:
            self._framebuffer = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._framebuffer)
            for storage, attachment in ((GL.GL_RGBA8, GL.GL_COLOR_ATTACHMENT0),
                                        (GL.GL_DEPTH_COMPONENT24, GL.GL_DEPTH_ATTACHMENT)):
                buffer = GL.glGenRenderbuffers(1)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, buffer)
                GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, storage, width, height)
                GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, buffer)
                self._renderbuffers.append(buffer)
        self._meshes = []  # (vertex array, vertex buffer, index buffer, index count)
        for positions, normals, triangles in meshes:
            vertex_array = GL.glGenVertexArrays(1)
            GL.glBindVertexArray(vertex_array)
            vertices = np.ascontiguousarray(np.hstack([positions, normals]), dtype=np.float32)
            vertex_buffer = GL.glGenBuffers(1)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, vertex_buffer)
            GL.glBufferData(GL.GL_ARRAY_BUFFER, vertices.nbytes, vertices, GL.GL_STATIC_DRAW)
            for location, offset in ((0, 0), (1, 12)):
                GL.glVertexAttribPointer(location, 3, GL.GL_FLOAT, GL.GL_FALSE, 24, ctypes.c_void_p(offset))
                GL.glEnableVertexAttribArray(location)
            indices = np.ascontiguousarray(triangles, dtype=np.uint32)
            index_buffer = GL.glGenBuffers(1)
            GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, index_buffer)
            GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, GL.GL_STATIC_DRAW)
            self._meshes.append((vertex_array, vertex_buffer, index_buffer, indices.size))
        self._instance_buffer = GL.glGenBuffers(1)
        self.reserve([capacity] * len(meshes))
        self._rgb = np.empty((height, width, 3), np.uint8)
        self._depth = np.empty((height, width), np.float32)
        GL.glBindVertexArray(0)

    @staticmethod
    def _link(vertex: str, fragment: str) -> int:
        program = GL.glCreateProgram()
        for source, kind in ((vertex, GL.GL_VERTEX_SHADER), (fragment, GL.GL_FRAGMENT_SHADER)):
            GL.glAttachShader(program, _compile(source, kind))
        GL.glLinkProgram(program)
        if not GL.glGetProgramiv(program, GL.GL_LINK_STATUS):
            raise RuntimeError(f"shader program did not link: {GL.glGetProgramInfoLog(program)!r}")
        return program

    def reserve(self, capacities: list[int]) -> None:
        """Room for ``capacities[k]`` instances of mesh ``k`` (reallocates only when growing)."""
        self.capacities = list(capacities)
        self.offsets = np.concatenate([[0], np.cumsum(self.capacities)[:-1]]).astype(int).tolist()
        self.instances = np.zeros((sum(self.capacities), ROW), np.float32)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._instance_buffer)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, self.instances.nbytes, None, GL.GL_DYNAMIC_DRAW)
        stride = ROW * 4
        for (vertex_array, *_), offset in zip(self._meshes, self.offsets):
            GL.glBindVertexArray(vertex_array)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._instance_buffer)
            for location, size, start in ((2, 4, 0), (3, 4, 4), (4, 4, 8), (5, 4, 12), (6, 3, 16), (7, 3, 19),
                                          (8, 2, 22)):
                GL.glVertexAttribPointer(location, size, GL.GL_FLOAT, GL.GL_FALSE, stride,
                                         ctypes.c_void_p((offset * ROW + start) * 4))
                GL.glEnableVertexAttribArray(location)
                GL.glVertexAttribDivisor(location, 1)
        GL.glBindVertexArray(0)

    def draw(self, counts: list[int], view: np.ndarray, projection: np.ndarray, camera: np.ndarray,
             light_direction: np.ndarray, light_radiance: np.ndarray, ambient: np.ndarray,
             background: np.ndarray) -> None:
        """Upload the used instance rows (one call) and draw every mesh's instances."""
        used = self.offsets[-1] + counts[-1]
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._framebuffer)
        GL.glViewport(0, 0, self.width, self.height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        # Every mesh is closed and wound outward, and every instance transform keeps handedness
        # (positive scales, right-handed bone frames): faces turned away are always hidden, so
        # culling them halves what llvmpipe rasterises and changes nothing but ties (measured:
        # CPU per frame of exchange's three bodies at 640×480 from 9.5 to 4.7 ms; 5 pixels of
        # 1.8 million in six frames differed, by one level). A projection that flips y (as
        # render.perspective does) turns the winding over.
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glFrontFace(GL.GL_CW if projection[0, 0] * projection[1, 1] < 0 else GL.GL_CCW)
        GL.glClearColor(*background, 1.0)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        for program, u in zip(self._programs, self._uniforms):
            GL.glUseProgram(program)
            GL.glUniformMatrix4fv(u["V"], 1, GL.GL_TRUE, view)
            GL.glUniformMatrix4fv(u["P"], 1, GL.GL_TRUE, projection)
            for name, value in (("cam_pos", camera), ("light_direction", light_direction),
                                ("light_radiance", light_radiance), ("ambient_light", ambient)):
                GL.glUniform3f(u[name], *value)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._instance_buffer)
        GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, used * ROW * 4, self.instances)
        for index, ((vertex_array, _, _, n_indices), count) in enumerate(zip(self._meshes, counts)):
            if count:
                GL.glUseProgram(self._programs[index in self._spheres])
                GL.glBindVertexArray(vertex_array)
                GL.glDrawElementsInstanced(GL.GL_TRIANGLES, n_indices, GL.GL_UNSIGNED_INT, ctypes.c_void_p(0), count)
        GL.glBindVertexArray(0)

    def read_colour(self, out: np.ndarray) -> np.ndarray:
        """The frame as RGB ``(height, width, 3)`` uint8 into ``out``, rows in framebuffer
        order (a projection that flips y makes that top row first). Read as RGB straight into
        ``out``: reading RGBA (the framebuffer's layout) is faster on llvmpipe by itself, but
        dropping the alpha afterwards costs more than it saves (measured at 640×480: 1.2 ms of
        CPU for RGB, 0.2 + 2.8 ms for RGBA and numpy's copy)."""
        target = out if out.flags.c_contiguous else self._rgb
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glReadPixels(0, 0, self.width, self.height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE, target)
        if target is not out:
            np.copyto(out, target)
        return out

    def read_depth(self) -> np.ndarray:
        """Window depth in [0, 1] (1 where nothing was drawn), rows as :meth:`read_colour`."""
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 4)
        GL.glReadPixels(0, 0, self.width, self.height, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, self._depth)
        return self._depth.copy()

    def delete(self) -> None:
        GL.glDeleteBuffers(1, [self._instance_buffer])
        for vertex_array, vertex_buffer, index_buffer, _ in self._meshes:
            GL.glDeleteVertexArrays(1, [vertex_array])
            GL.glDeleteBuffers(2, [vertex_buffer, index_buffer])
        if self._framebuffer:
            GL.glDeleteRenderbuffers(len(self._renderbuffers), self._renderbuffers)
            GL.glDeleteFramebuffers(1, [self._framebuffer])
        for program in self._programs:
            GL.glDeleteProgram(program)

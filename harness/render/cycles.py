"""The Blender (Cycles) translation: build a :class:`scenes.model.SceneSpec` as a bpy scene and render cameras.

This is the ONLY module of tri360 that imports ``bpy``, and only the Cycles worker process
(:mod:`harness.render.cycles_worker`, started by :class:`harness.render.cycles_renderer.CyclesRenderer`) loads it,
with ``importlib``, so neither ``import harness.cli`` nor a render job's own process ever loads Blender.

Usage (inside the worker)::

    scene = SceneRenderer(spec, RenderSettings(width=1000, samples=20))   # builds the bpy scene once
    image, distance = scene.render_camera("C", pose, workdir)             # (H, W, 3) uint8, (H, W) float32 m

What a render is (the choices a reader of the data needs to know):

- Cycles on the CPU, equirectangular panoramic cameras (``PANO`` / ``EQUIRECTANGULAR``), adaptive sampling
  off (``samples`` means samples per pixel), fixed seed, optional OpenImageDenoise (albedo + normal guides).
- Each camera is written by Cycles straight to a multi-layer EXR (Combined + Depth).  The Depth pass of a
  panoramic camera is the Euclidean distance to the surface seen through the pixel centre (sample 0), so
  it is exact ground truth whatever the sample count or denoiser; Cycles' 1e10 "no hit" becomes +inf.
- Colour: Combined is scene-linear Rec.709.  We apply the **Standard** view transform ourselves with
  :func:`harness.render.base.srgb_encode` (exposure 0, gamma 1, no look): clip to [0, 1], sRGB transfer
  function, round to 8 bits.  This equals what Blender's own 'Standard' PNG output gives, and avoids AgX's
  tone curve (which would make colour depend on the view transform rather than on the surface).
- Camera pose: tri360 camera axes are X right, Y forward, Z up.  A Blender camera looks along its local
  -Z with local +Y up, so its world matrix has columns ``[X, Z, -Y]`` of our pose (equivalently: a camera
  object with ``rotation_euler = (90 deg, 0, 0)`` relative to the rig).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import bpy
import mathutils
import numpy as np

from harness.data.exr import distance_map, float_channel, read_exr_channels
from harness.render.base import RenderSettings, srgb_encode
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose
from scenes.model import CYLINDER_AXES, Box, Cylinder, Light, Material, ModelFile, SceneSpec, Sphere

DEPTH_CHANNEL = "ViewLayer.Depth.Z"
COMBINED_LAYER = "ViewLayer.Combined"
VIEW_TRANSFORM = "Standard"


# ------------------------------------------------------------------------------------------- materials
#
# Each material kind is a *pattern* (a scalar field in [0, 1] over object-space coordinates measured in
# units of ``Material.scale`` metres) plus *surface* settings.  The pattern drives a colour ramp from
# ``color`` to ``color + contrast * (color2 - color)``, so ``contrast = 0`` is a uniform surface.


def _coords(nt, mat: Material, stretch=(1.0, 1.0, 1.0)):
    """Object-space coordinates divided by ``mat.scale`` (and stretched per axis) -> vector socket."""
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mp = nt.nodes.new("ShaderNodeMapping")
    s = 1.0 / max(mat.scale, 1e-6)
    mp.inputs["Scale"].default_value = (s * stretch[0], s * stretch[1], s * stretch[2])
    nt.links.new(tc.outputs["Object"], mp.inputs["Vector"])
    return mp.outputs["Vector"]


def _noise(nt, vec, scale=1.0, detail=4.0, roughness=0.5):
    n = nt.nodes.new("ShaderNodeTexNoise")
    n.inputs["Scale"].default_value = scale
    n.inputs["Detail"].default_value = detail
    n.inputs["Roughness"].default_value = roughness
    nt.links.new(vec, n.inputs["Vector"])
    return n.outputs["Fac"]


def _pattern_paint(nt, mat):
    """Faint multi-octave noise (painted plaster)."""
    return _noise(nt, _coords(nt, mat), scale=1.0, detail=4.0, roughness=0.6), (0.3, 0.7)


def _pattern_noise(nt, mat):
    """Strong, detailed noise: a richly textured synthetic surface."""
    return _noise(nt, _coords(nt, mat), scale=1.0, detail=6.0, roughness=0.65), (0.25, 0.75)


def _pattern_wood(nt, mat):
    """Wavy grain lines running along object X (wave bands across Y, distorted by noise)."""
    w = nt.nodes.new("ShaderNodeTexWave")
    w.wave_type = "BANDS"
    w.bands_direction = "Y"
    w.wave_profile = "SAW"
    w.inputs["Scale"].default_value = 1.0
    w.inputs["Distortion"].default_value = 6.0
    w.inputs["Detail"].default_value = 3.0
    w.inputs["Detail Scale"].default_value = 1.5
    nt.links.new(_coords(nt, mat, stretch=(0.15, 1.0, 1.0)), w.inputs["Vector"])
    return w.outputs["Fac"], (0.0, 1.0)


def _pattern_tiles(nt, mat):
    """Square tiles of side ``scale`` (object XY), random shade per tile, light grout lines."""
    b = nt.nodes.new("ShaderNodeTexBrick")
    b.offset = 0.0
    b.squash = 1.0
    b.inputs["Color1"].default_value = (0.15, 0.15, 0.15, 1.0)
    b.inputs["Color2"].default_value = (0.55, 0.55, 0.55, 1.0)
    b.inputs["Mortar"].default_value = (1.0, 1.0, 1.0, 1.0)
    b.inputs["Scale"].default_value = 1.0
    b.inputs["Mortar Size"].default_value = 0.015
    b.inputs["Brick Width"].default_value = 1.0
    b.inputs["Row Height"].default_value = 1.0
    nt.links.new(_coords(nt, mat), b.inputs["Vector"])
    # add a little speckle so tiles are not perfectly flat
    mix = nt.nodes.new("ShaderNodeMath")
    mix.operation = "MULTIPLY_ADD"
    nt.links.new(_noise(nt, _coords(nt, mat), scale=8.0, detail=2.0), mix.inputs[0])
    mix.inputs[1].default_value = 0.25
    nt.links.new(b.outputs["Color"], mix.inputs[2])
    return mix.outputs["Value"], (0.1, 1.1)


def _pattern_board(nt, mat):
    """Chalkboard: large soft smudges plus fine dust."""
    return _noise(nt, _coords(nt, mat), scale=1.0, detail=5.0, roughness=0.7), (0.3, 0.75)


def _pattern_fabric(nt, mat):
    """Fabric: fine, high-frequency weave noise."""
    return _noise(nt, _coords(nt, mat), scale=4.0, detail=6.0, roughness=0.8), (0.3, 0.7)


def _pattern_metal(nt, mat):
    """Brushed metal: noise stretched along object X."""
    return _noise(nt, _coords(nt, mat, stretch=(0.05, 1.0, 1.0)), scale=2.0, detail=4.0), (0.3, 0.7)


def _pattern_plastic(nt, mat):
    """Moulded plastic: soft, low-frequency mottling."""
    return _noise(nt, _coords(nt, mat), scale=1.0, detail=3.0, roughness=0.4), (0.35, 0.65)


_PATTERNS: dict[str, Callable] = {
    "paint": _pattern_paint, "noise": _pattern_noise, "wood": _pattern_wood, "tiles": _pattern_tiles,
    "board": _pattern_board, "fabric": _pattern_fabric, "metal": _pattern_metal, "plastic": _pattern_plastic,
    "glass": _pattern_plastic, "emission": _pattern_paint,
}

# Principled BSDF inputs per kind (besides Base Color and Roughness, which come from the Material).
_SURFACE: dict[str, dict] = {
    "paint": {}, "noise": {}, "wood": {"Coat Weight": 0.2}, "tiles": {"Coat Weight": 0.1}, "board": {},
    "fabric": {"Sheen Weight": 0.3}, "metal": {"Metallic": 1.0}, "plastic": {"Specular IOR Level": 0.5},
    "glass": {"Transmission Weight": 1.0, "IOR": 1.45},
}


def _build_material(mat: Material):
    bm = bpy.data.materials.new(mat.name)
    bm.use_nodes = True
    nt = bm.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    fac, (lo, hi) = _PATTERNS[mat.kind](nt, mat)
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    c1 = np.asarray(mat.color, float)
    c2 = c1 + float(mat.contrast) * (np.asarray(mat.secondary, float) - c1)
    e0, e1 = ramp.color_ramp.elements[0], ramp.color_ramp.elements[1]
    e0.position, e1.position = lo, hi
    e0.color, e1.color = (*c1, 1.0), (*c2, 1.0)
    nt.links.new(fac, ramp.inputs["Fac"])
    if mat.kind == "emission":
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = float(mat.emission)
        nt.links.new(ramp.outputs["Color"], em.inputs["Color"])
        nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
        return bm
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = float(mat.roughness)
    for key, value in _SURFACE[mat.kind].items():
        bsdf.inputs[key].default_value = value
    nt.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return bm


# -------------------------------------------------------------------------------------------- geometry

_CUBE_VERTS = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
# outward-facing quads (counter-clockwise seen from outside) over _CUBE_VERTS (index = 4x + 2y + z)
_CUBE_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def _build_box(box: Box, index: int, materials: dict, collection) -> None:
    sx, sy, sz = box.size
    verts = [(x * sx, y * sy, z * sz) for x, y, z in _CUBE_VERTS]
    faces = [tuple(reversed(f)) for f in _CUBE_FACES] if box.inward else _CUBE_FACES
    name = box.name or f"box{index:04d}"
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    me.materials.append(materials[box.material])
    ob = bpy.data.objects.new(name, me)
    ob.location = box.center
    ob.rotation_euler = (0.0, 0.0, float(box.yaw))
    collection.objects.link(ob)


TESSELLATION_TOL_M = 2.5e-4
"""Largest distance between a round shape's mesh and the analytic surface, metres.  The Depth pass is the
distance to the mesh, so this bounds how far Cycles' ground truth is from the analytic shape (and from the
ray-caster): vertices sit slightly outside the surface so the mesh straddles it (out at the vertices, in at
the middle of each face), the segment count grows with the square root of the radius."""
MIN_SEGMENTS, MAX_SEGMENTS = 16, 512


def round_segments(radius: float, kind: str) -> int:
    """Segments around a cylinder (``kind="cylinder"``) or a UV sphere (``"sphere"``, even) of ``radius`` m so that
    the straddling mesh deviates from the surface by at most ``TESSELLATION_TOL_M``.

    A straddling polygon of N sides deviates by about r (pi/N)^2 / 4; a UV sphere's quad by about r (pi/N)^2 / 2.
    """
    k = 4.0 if kind == "cylinder" else 2.0
    n = int(np.ceil(np.pi * np.sqrt(radius / (k * TESSELLATION_TOL_M))))
    n = int(np.clip(n, MIN_SEGMENTS, MAX_SEGMENTS))
    return n + (n % 2) if kind == "sphere" else n


def cylinder_mesh(cyl: Cylinder) -> tuple[np.ndarray, list]:
    """Vertices (2N, 3) in the cylinder's yaw frame (metres, centred) and faces (N side quads, 2 caps, outward)."""
    n = round_segments(cyl.radius, "cylinder")
    rv = 2.0 * cyl.radius / (1.0 + np.cos(np.pi / n))  # vertex radius: the polygon straddles the circle
    a = 2.0 * np.pi * np.arange(n) / n
    u, v = rv * np.cos(a), rv * np.sin(a)
    h = cyl.length / 2.0
    uvw = np.concatenate([np.column_stack([u, v, np.full(n, -h)]), np.column_stack([u, v, np.full(n, h)])])
    k = CYLINDER_AXES.index(cyl.axis)
    verts = np.empty_like(uvw)
    verts[:, (k + 1) % 3], verts[:, (k + 2) % 3], verts[:, k] = uvw[:, 0], uvw[:, 1], uvw[:, 2]
    faces = [(i, (i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    faces += [tuple(range(n - 1, -1, -1)), tuple(range(n, 2 * n))]
    return verts, faces


def sphere_mesh(sph: Sphere) -> tuple[np.ndarray, list]:
    """UV-sphere vertices (centred, metres) and faces (outward), straddling the sphere (see ``round_segments``)."""
    n = round_segments(sph.radius, "sphere")
    m = n // 2
    c = np.cos(np.pi / n)
    rv = 2.0 * sph.radius / (1.0 + c * c)
    polar = np.pi * np.arange(1, m) / m
    az = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([np.outer(np.sin(polar), np.cos(az)), np.outer(np.sin(polar), np.sin(az)),
                     np.outer(np.cos(polar), np.ones(n))], axis=-1).reshape(-1, 3)
    verts = rv * np.concatenate([[(0.0, 0.0, 1.0)], ring, [(0.0, 0.0, -1.0)]])
    top, bottom = 0, 1 + (m - 1) * n

    def idx(j, i):  # ring j (0 = nearest the top), azimuth i
        return 1 + j * n + i % n

    faces = [(top, idx(0, i), idx(0, i + 1)) for i in range(n)]
    faces += [(idx(j, i), idx(j + 1, i), idx(j + 1, i + 1), idx(j, i + 1)) for j in range(m - 2) for i in range(n)]
    faces += [(bottom, idx(m - 2, i + 1), idx(m - 2, i)) for i in range(n)]
    return verts, faces


def _build_round(shape, index: int, materials: dict, collection) -> None:
    verts, faces = cylinder_mesh(shape) if isinstance(shape, Cylinder) else sphere_mesh(shape)
    name = shape.name or f"{type(shape).__name__.lower()}{index:04d}"
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts.tolist(), [], faces)
    smooth = [len(f) <= 4 for f in faces]  # shaded round; a cylinder's caps (n-gons) stay flat
    me.polygons.foreach_set("use_smooth", smooth)
    me.update()
    me.materials.append(materials[shape.material])
    ob = bpy.data.objects.new(name, me)
    ob.location = shape.center
    ob.rotation_euler = (0.0, 0.0, float(getattr(shape, "yaw", 0.0)))
    collection.objects.link(ob)


def _build_light(light: Light, index: int, collection) -> None:
    kind = {"area": "AREA", "point": "POINT", "sun": "SUN"}.get(light.kind)
    if kind is None:
        raise ValueError(f"light {index}: unknown kind {light.kind!r} (area, point, sun)")
    data = bpy.data.lights.new(f"light{index:03d}", kind)
    data.color = light.color
    data.energy = float(light.power)
    if kind == "AREA":
        data.shape = "RECTANGLE"
        data.size, data.size_y = float(light.size[0]), float(light.size[1])
    ob = bpy.data.objects.new(f"light{index:03d}", data)
    ob.location = light.position
    ob.visible_camera = False  # lights never appear in the image or in the ground-truth distance
    collection.objects.link(ob)


def _import_model(model: ModelFile, collection) -> list:
    """Import a .blend/.glb/.gltf/.obj file, place its root objects by the model's transform."""
    path = Path(model.path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"model file {path} does not exist")
    before = set(bpy.data.objects)
    suffix = path.suffix.lower()
    if suffix == ".blend":
        with bpy.data.libraries.load(str(path), link=False) as (src, dst):
            dst.objects = list(src.objects)
        for ob in dst.objects:
            if ob is not None and ob.type not in ("CAMERA",):
                collection.objects.link(ob)
    elif suffix in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=str(path))
    elif suffix == ".obj":
        bpy.ops.wm.obj_import(filepath=str(path), forward_axis="Y", up_axis="Z")
    else:
        raise ValueError(f"model file {path}: unsupported format {suffix!r} (.blend, .glb, .gltf, .obj)")
    new = [ob for ob in bpy.data.objects if ob not in before]
    for ob in new:
        if ob.type == "CAMERA":  # a model's own cameras must not replace ours
            bpy.data.objects.remove(ob)
    new = [ob for ob in bpy.data.objects if ob not in before]
    place = (mathutils.Matrix.Translation(model.location)
             @ mathutils.Euler(model.rotation_euler).to_matrix().to_4x4()
             @ mathutils.Matrix.Scale(float(model.scale), 4))
    for ob in new:
        if ob.parent is None:
            ob.matrix_world = place @ ob.matrix_world
    return new


# ---------------------------------------------------------------------------------------------- camera


def blender_camera_matrix(pose: CameraPose) -> np.ndarray:
    """(4, 4) Blender world matrix for a tri360 camera pose: rotation columns [X, Z, -Y], translation = position."""
    r = np.asarray(pose.rotation, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = np.stack([r[:, 0], r[:, 2], -r[:, 1]], axis=1)
    m[:3, 3] = np.asarray(pose.position, dtype=np.float64)
    return m


def _read_render(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A Cycles multi-layer (multi-part) EXR -> ((H, W, 3) float32 linear RGB of the Combined layer,
    (H, W) float32 distance in metres from the Depth pass, +inf = no surface)."""
    channels = read_exr_channels(path)
    rgb = np.stack([float_channel(channels, path, f"{COMBINED_LAYER}.{c}") for c in "RGB"], axis=-1)
    return rgb, distance_map(float_channel(channels, path, DEPTH_CHANNEL), path, DEPTH_CHANNEL)


# -------------------------------------------------------------------------------------------- renderer


class SceneRenderer:
    """A built Blender scene for one :class:`SceneSpec`; renders single cameras.

    The constructor resets Blender to an empty factory scene and builds materials, boxes, lights and models
    once; :meth:`render_camera` only moves the camera, so consecutive cameras and viewpoints reuse the synced
    scene (``render.use_persistent_data``).  Only one SceneRenderer is meaningful at a time (bpy is global
    state), which is one reason it lives in its own worker process.
    """

    def __init__(self, spec: SceneSpec, settings: RenderSettings):
        settings.check()
        spec.validate()
        self.spec = spec
        self.settings = settings
        bpy.ops.wm.read_factory_settings(use_empty=True)
        self.scene = bpy.context.scene
        self._configure()
        coll = self.scene.collection
        mats = {name: _build_material(m) for name, m in spec.materials.items()}
        for i, box in enumerate(spec.boxes):
            _build_box(box, i, mats, coll)
        for i, shape in enumerate([*spec.cylinders, *spec.spheres]):
            _build_round(shape, i, mats, coll)
        for i, light in enumerate(spec.lights):
            _build_light(light, i, coll)
        for model in spec.models:
            _import_model(model, coll)
        self.cameras = {}
        for name in CAMERA_NAMES:
            cam = bpy.data.cameras.new(name)
            cam.type = "PANO"
            cam.panorama_type = "EQUIRECTANGULAR"
            cam.clip_start = 1e-3
            cam.clip_end = 1e5
            ob = bpy.data.objects.new(name, cam)
            coll.objects.link(ob)
            self.cameras[name] = ob

    def _configure(self) -> None:
        s, sc = self.settings, self.scene
        r = sc.render
        r.engine = "CYCLES"
        r.resolution_x, r.resolution_y, r.resolution_percentage = s.width, s.height, 100
        r.use_persistent_data = True
        r.use_compositing = False
        r.use_sequencer = False
        r.threads_mode = "FIXED" if s.threads > 0 else "AUTO"
        if s.threads > 0:
            r.threads = s.threads
        r.filter_size = s.filter_width  # Blackman-Harris width, pixels
        cy = sc.cycles
        cy.device = "CPU"
        cy.samples = s.samples
        cy.use_adaptive_sampling = s.adaptive_threshold > 0
        if s.adaptive_threshold > 0:
            cy.adaptive_threshold = s.adaptive_threshold
            cy.adaptive_min_samples = s.adaptive_min_samples
        cy.seed = s.seed
        cy.use_animated_seed = False
        cy.use_denoising = s.denoise
        if s.denoise:
            cy.denoiser = "OPENIMAGEDENOISE"
            cy.denoising_input_passes = "RGB_ALBEDO_NORMAL"
            cy.denoising_prefilter = s.denoise_prefilter
            cy.denoising_quality = s.denoise_quality
            cy.denoising_use_gpu = False
        cy.max_bounces = s.max_bounces
        cy.diffuse_bounces = min(s.max_bounces, s.diffuse_bounces)
        cy.glossy_bounces = min(s.max_bounces, s.glossy_bounces)
        cy.transmission_bounces = max(s.max_bounces, 4)
        cy.transparent_max_bounces = 8
        cy.volume_bounces = 0
        cy.caustics_reflective = False
        cy.caustics_refractive = False
        cy.sample_clamp_direct = 0.0
        cy.sample_clamp_indirect = s.clamp_indirect
        cy.use_light_tree = s.light_tree
        cy.use_fast_gi = False
        sc.view_settings.view_transform = VIEW_TRANSFORM
        sc.view_settings.look = "None"
        sc.view_settings.exposure = 0.0
        sc.view_settings.gamma = 1.0
        vl = sc.view_layers[0]
        vl.use_pass_combined = True
        vl.use_pass_z = True
        im = r.image_settings
        im.media_type = "MULTI_LAYER_IMAGE"  # Blender 5.0: must precede file_format
        im.file_format = "OPEN_EXR_MULTILAYER"
        im.color_depth = "32"
        im.exr_codec = "ZIP"
        world = bpy.data.worlds.new("world")
        world.use_nodes = True
        bg = world.node_tree.nodes.get("Background") or world.node_tree.nodes.new("ShaderNodeBackground")
        bg.inputs["Color"].default_value = (*self.spec.background, 1.0)
        bg.inputs["Strength"].default_value = 1.0
        sc.world = world

    def engine_info(self) -> dict:
        """What Cycles actually ran with (read back from the bpy scene), for frame provenance."""
        s, cy = self.settings, self.scene.cycles
        return {
            "engine": "CYCLES", "versions": {"blender": bpy.app.version_string}, "device": "CPU",
            "threads": s.threads or os.cpu_count(),
            "adaptive_sampling": ({"threshold": s.adaptive_threshold, "min_samples": s.adaptive_min_samples}
                                  if s.adaptive_threshold > 0 else False),
            "denoiser": "OPENIMAGEDENOISE" if s.denoise else "none",
            "denoiser_settings": ({"input_passes": "RGB_ALBEDO_NORMAL", "prefilter": s.denoise_prefilter,
                                   "quality": s.denoise_quality} if s.denoise else None),
            "bounces": {k: getattr(cy, f"{k}_bounces") for k in ("max", "diffuse", "glossy", "transmission",
                                                                   "volume")}
                       | {"transparent": cy.transparent_max_bounces},
            "caustics": {"reflective": cy.caustics_reflective, "refractive": cy.caustics_refractive},
            "light_tree": cy.use_light_tree, "fast_gi": cy.use_fast_gi,
            "pixel_filter": {"type": "BLACKMAN_HARRIS", "width_px": s.filter_width},
            "clamp_indirect": s.clamp_indirect, "view_transform": VIEW_TRANSFORM,
            "distance": "Cycles Depth pass (panoramic camera: Euclidean, pixel centre, sample 0)",
        }

    def render_camera(self, name: str, pose: CameraPose, workdir: Path) -> tuple[np.ndarray, np.ndarray]:
        """Render one camera -> ((H, W, 3) uint8 sRGB, (H, W) float32 distance in metres, +inf = no surface).

        Cycles writes ``<workdir>/<name>.exr``, which is read and removed.
        """
        ob = self.cameras[name]
        ob.matrix_world = mathutils.Matrix(blender_camera_matrix(pose).tolist())
        self.scene.camera = ob
        path = Path(workdir) / f"{name}.exr"
        self.scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True, scene=self.scene.name)
        if not path.is_file():
            raise RuntimeError(f"Cycles wrote no image for camera {name}")
        try:
            rgb, distance = _read_render(path)
        finally:
            path.unlink(missing_ok=True)
        return srgb_encode(rgb), distance


__all__ = ["RenderSettings", "SceneRenderer", "blender_camera_matrix", "DEPTH_CHANNEL", "TESSELLATION_TOL_M",
           "round_segments", "cylinder_mesh", "sphere_mesh"]

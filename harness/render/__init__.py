"""Renderers: turn a :class:`scenes.model.SceneSpec` and a rig into a :class:`harness.data.frame.Frame`.

- :mod:`harness.render.base`: ``RenderSettings`` (every render default, once), the ``Renderer`` interface and its
  shared implementation ``BaseRenderer``, ``srgb_encode`` and the provenance writer;
- :mod:`harness.render.registry`: renderers by name (``open_renderer("cycles" | "raycast", spec, settings)``);
- :mod:`harness.render.raycast`: the numpy ray-caster (boxes, exact distance, no Blender);
- :mod:`harness.render.camera`: the photometric camera model (exposure, white balance, fall-off, response, noise,
  JPEG: what a real camera does to the light before its image is stored);
- :mod:`harness.render.cycles_renderer`: Blender Cycles, driven in a worker process
  (:mod:`harness.render.cycles_worker`) that alone loads :mod:`harness.render.cycles`, the only ``bpy`` import.

Importing this package does no work and never loads Blender.
"""

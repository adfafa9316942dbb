"""tri360 scenes: renderer-agnostic scene descriptions and their registry (no Blender here).

- :mod:`scenes.model`: the scene description data classes (``SceneSpec``, ``Box``, ``Material``, ``Light``,
  ``ModelFile``), the registry entry ``SceneEntry`` (with ``SceneError``), a family's parameters (``SceneParams``,
  ``param``, ``ParameterError``) and ``choose_viewpoints``;
- :mod:`scenes.registry`: ``discover()`` (files in ``scenes/families/`` and the entry point
  group ``tri360.scenes``) and ``get_scene("family[:preset]")``;
- ``scenes/families/``: one file per scene family.

Importing this package does no work; a renderer (``harness.render``) turns a ``SceneSpec`` into pixels.
"""

"""Renderers by name: the ``--renderer`` choices.

``cycles`` runs Blender in a worker process (this process never imports ``bpy``); ``raycast`` is numpy.
"""

from __future__ import annotations

from harness.data.errors import UserError
from harness.render.base import BaseRenderer, RenderSettings
from harness.render.cycles_renderer import CyclesRenderer
from harness.render.raycast import RaycastRenderer
from scenes.model import SceneSpec

__all__ = ["RENDERER_CLASSES", "available_renderers", "get_renderer", "open_renderer"]

#: renderer name -> its backend class; the names are those a scene may name as its default
#: (``scenes.model.RENDERERS``)
RENDERER_CLASSES: dict[str, type[BaseRenderer]] = {cls.name: cls for cls in (CyclesRenderer, RaycastRenderer)}


def available_renderers() -> list[str]:
    """The ``--renderer`` names, sorted."""
    return sorted(RENDERER_CLASSES)


def get_renderer(name: str) -> type[BaseRenderer]:
    """The renderer class called ``name``; raises UserError listing the known names."""
    if name not in RENDERER_CLASSES:
        raise UserError(f"unknown renderer {name!r} (known: {', '.join(available_renderers())})")
    return RENDERER_CLASSES[name]


def open_renderer(name: str, spec: SceneSpec, settings: RenderSettings, verbose: bool = False) -> BaseRenderer:
    """Build renderer ``name`` for ``spec`` (use as a context manager, or call ``close()``).

    Raises:
        UserError: unknown renderer, or a scene it cannot draw (naming the scene and the reason).
    """
    return get_renderer(name)(spec, settings, verbose=verbose)

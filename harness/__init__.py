"""tri360 harness: the frame format and its I/O, the renderers, the commands, their runtime and the CLI.

Only ``harness.render.cycles`` imports ``bpy``; everything else here is plain numpy.
"""

__version__ = "0.1.0"

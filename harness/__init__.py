"""tri360 harness: the rig, the frame format, scene kit, job running and the CLI.

Only ``harness.render.cycles`` imports ``bpy``; everything else here is plain numpy.
"""

__version__ = "0.1.0"

"""tri360 reconstruction: pure numpy/OpenCV, never Blender.

Equirectangular camera model, flow backends (on rectified or plain pairs), spherical triangulation,
weights and per-pixel Levenberg-Marquardt refinement variants, and the pipeline that ties them together.
"""

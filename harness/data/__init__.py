"""The data layer: on-disk formats and safe writing (numpy, OpenCV, OpenEXR, pandas; no renderer, no plots).

- ``errors``: :class:`UserError` / :class:`FrameError`, the one-line errors the CLI prints.
- ``atomic``: atomic file and directory writes that respect the umask, safe under concurrent writers, and the
  clean-up of what killed runs leave behind.
- ``native``: keeps C-library messages (libpng, OpenEXR) off the terminal while a file is decoded.
- ``exr``: the one OpenEXR reader (every part, damaged-file detection) and single-channel float32 maps.
- ``images``: 8-bit PNG images.
- ``frame``: the ``tri360-frame/1`` format: read, validate (including impossible rigs), write.
- ``results``: results sets (results/regions/breakdown CSVs, frames.json, config.json, the maps' layout),
  read and written with the columns of ``reports.schema``.
"""

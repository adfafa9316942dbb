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
- ``jsonio``: strict JSON for everything tri360 writes (NaN and infinities as ``null``, numpy values converted).
- ``names``: the one rule for names that become path components (method labels, scenes, viewpoints, study points).
- ``outputs``: output locations: the marker of what tri360 wrote, checks before any work, result sets swapped in
  whole.
- ``provenance``: which tri360 (version, git commit) produced an output.
- ``photometric``: a camera's photometric record in ``frame.json`` (exposure, white balance, fall-off, noise,
  response, JPEG).
- ``predictions``: the ``tri360-pred/1`` format any method hands to ``tri360 score``.
- ``suite``: benchmark suites (``tri360-suite/1``): frames by recipe, split into dev, test and train, with their
  camera conditions.
- ``layouts``: the dataset layouts learned 360-degree stereo methods read, and the conversions to and from frames.
- ``loader``: a framework-neutral dataset of frames (``FrameDataset``) for training and evaluating learned methods.
"""

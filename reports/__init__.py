"""tri360 reports: metrics, the results schema, results tables, plots, point clouds and the self-contained HTML
report.

Pure: arrays, frames and DataFrames in; DataFrames, figures (PNG bytes), bytes and text out.  Imports only
``reconstruction`` among tri360's packages, never touches a file (``harness.data.results`` reads and writes
results sets, ``harness.commands.report`` writes the report) and never imports Blender.  Importing this package does
no work: import the sub-modules you need, e.g. ``from reports.metrics import summary, breakdown`` or
``from reports.sections import frame_part``.
"""

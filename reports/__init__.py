"""tri360 reports: metrics, results tables, plots, point clouds and the self-contained HTML report.

Pure numpy / pandas / matplotlib (Agg, no pyplot state); never imports Blender.  Importing this package
does no work: import the sub-modules you need, e.g. ``from reports.metrics import summary, breakdown`` or
``from reports.build import write_report``.
"""

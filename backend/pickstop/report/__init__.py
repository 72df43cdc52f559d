"""A plan as documents to hand on: a self-contained HTML report with a top-view drawing, and
the stops as CSV.

Pure functions of a plan and the scene document it was planned from (no web framework, no
database): the REST API serves them for stored plans (``GET /plans/{id}/report`` and
``/stops.csv``), and anything else may call them on a plan it holds.
"""

"""The offline tool: `gcs-ppf plan` (timed planning, outputs, plots) and the planner benchmark."""

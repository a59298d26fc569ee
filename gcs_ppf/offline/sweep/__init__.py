"""`gcs-ppf sweep`: plan many random scenes of a family, locally or on a Ray cluster, and
summarise them (a table, figures)."""

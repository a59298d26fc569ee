"""The planner, pure: scene arrays, PPF kernel and reference, APF, rollout, metrics; no I/O."""

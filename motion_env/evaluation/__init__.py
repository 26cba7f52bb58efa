"""Evaluation: metric definitions (``docs/metrics.md``), the route-following suite and the bench."""

"""Evaluation: metric definitions (``docs/metrics.md``), the route-following suite, joint control,
caption recognition, naturalness and the bench. Each evaluation takes a generator and a settings
dataclass and returns a result object; ``motion_env.cli`` parses, prints and writes JSON."""

"""Classical methods optikin compares its optimisation-based solutions with (seed literature baselines)."""

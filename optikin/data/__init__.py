"""Sources of samples: synthetic generators (seeded) and readers of recorded files."""

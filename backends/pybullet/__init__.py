"""backends/pybullet."""

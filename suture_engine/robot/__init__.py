"""suture_engine/robot."""

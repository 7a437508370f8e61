"""suture_engine/validation."""

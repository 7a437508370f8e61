"""suture_engine/control."""

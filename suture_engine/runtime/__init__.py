"""suture_engine/runtime."""

"""suture_engine/language."""

"""suture_engine/suture."""

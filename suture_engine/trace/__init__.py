"""suture_engine/trace."""

"""Examples of agents written against the public agent protocol (see direction_follower.py)."""

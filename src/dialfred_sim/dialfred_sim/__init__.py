"""DialFRED household simulator: a pybullet world with ALFRED's object types and actions."""

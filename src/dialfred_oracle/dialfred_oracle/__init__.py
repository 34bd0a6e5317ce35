"""DialFRED oracle: location/appearance/direction answers and the /oracle/answer node; filled by a later issue (the oracle)."""

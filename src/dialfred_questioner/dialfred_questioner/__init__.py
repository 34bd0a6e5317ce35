"""DialFRED questioner: decides when and what to ask the oracle; filled by a later issue (the questioner model)."""

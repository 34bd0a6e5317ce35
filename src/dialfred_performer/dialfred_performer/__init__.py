"""DialFRED performer: the instruction-following agent acting in the simulator; filled by a later issue (the performer model)."""

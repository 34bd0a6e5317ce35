"""DialFRED questioner: decides when and what to ask the oracle.

`baselines` holds the questioners that need no training (random, all questions) and `with_questioner`,
which gives any agent a questioner. The learned LSTM questioner comes with a later issue.
"""

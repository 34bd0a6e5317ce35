"""DialFRED oracle: location, appearance and direction answers from the simulator's ground truth.

`answers` (the rules, ROS-free), `node` (`/oracle/answer`, with a real-person mode), `in_process` (the same
answers in the process of a DialfredEnv, and `EnvServer`, which serves an episode's requests there),
`annotator` (the synthetic dialogue annotators), `nouns` and `colours` (the words answers use).
"""

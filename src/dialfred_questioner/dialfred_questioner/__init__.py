"""DialFRED questioner: decides when and what to ask the oracle.

`baselines` holds the questioners that need no training (random, all questions, model confusion) and
`with_questioner`, which gives any agent a questioner; `model`, `pretrain`, `rollout`, `rl`, `finetune`
and `policy` the learned LSTM questioner (pre-trained, then fine-tuned with actor-critic RL);
`questioners.make_questioner` makes any of them by name; `node` serves `/questioner/ask`.
"""

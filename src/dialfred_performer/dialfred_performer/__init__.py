"""DialFRED performer: the Episodic-Transformer agent that follows the instruction and the dialogue.

ROS-free core: `preprocess` (instruction + dialogue -> tokens, frames -> tensors; the one path of
training and evaluation), `nn/` (one module per part), `model` (PerformerConfig, Performer, loss,
checkpoints), `data` (demonstrations + dialogues as padded batches), `agent` (PerformerAgent),
`prepare` (a split's demonstrations, dialogues.jsonl and vocabulary: `./dialfred prepare-performer`),
`train` (the training entry point, `TrainConfig` is its command line: `./dialfred train-performer`),
`cli` (a config dataclass as argparse), `curves` (metrics.jsonl -> curves.png), `distributed` (training
over torchrun processes). `node`: the RunTask action server that plays a goal through the graph.
"""

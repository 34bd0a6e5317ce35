"""DialFRED performer: the Episodic-Transformer agent that follows the instruction and the dialogue.

ROS-free core: `preprocess` (instruction + dialogue -> tokens, frames -> tensors; the one path of
training and evaluation), `nn/` (one module per part), `model` (PerformerConfig, Performer, loss,
checkpoints), `data` (demonstrations + dialogues as padded batches), `agent` (PerformerAgent).
The training entry point and the ROS node come with the rest of issue 11.
"""

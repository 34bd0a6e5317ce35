"""The performer's models by name, as the node's `model` parameter and `launch eval --agent/--performer`
name them: `et` (the Episodic Transformer, `agent.PerformerAgent`) and `map` (the map-and-plan
performer over the checkpoint's perception network, `mapper.agent.MapAgent`). No ROS."""

from __future__ import annotations

from pathlib import Path

PERFORMER_MODELS = ('et', 'map')
# The map performer's camera: 128 px frames, area-averaged down to its network's input. Over
# the shipped et.pt's network (64 px), valid_unseen instruction only: 45.0 SR, against 41.7 with a camera
# of the network's own 64 px (an averaged frame keeps objects thinner than one of the network's pixels).
MAP_CAMERA = 128


def load_policy(model: str, path: Path):
    """The policy of `model` from checkpoint `path`. FileNotFoundError when there is no file; ValueError
    (a CheckpointError among them) for an unknown model or a checkpoint the model cannot use."""
    if model == 'et':
        from .agent import PerformerAgent
        return PerformerAgent.from_checkpoint(Path(path))
    if model == 'map':
        from .mapper.agent import MapAgent
        return MapAgent.from_checkpoint(Path(path))
    raise ValueError(f'unknown performer model {model!r}; expected one of {", ".join(PERFORMER_MODELS)}')


def camera_resolution(model: str, path: Path) -> int:
    """The camera pixels `model` plays at: the et performer's training resolution, read from its checkpoint
    `path` (a frame of another size would be area-averaged, not the rendering it learned from); MAP_CAMERA
    for the map performer. FileNotFoundError / ValueError as load_policy."""
    if model == 'et':
        from .model import load_checkpoint
        return int(load_checkpoint(Path(path))[0].config.resolution)
    if model == 'map':
        return MAP_CAMERA
    raise ValueError(f'unknown performer model {model!r}; expected one of {", ".join(PERFORMER_MODELS)}')

"""The performer's models by name, as the node's `model` parameter and `launch eval --agent/--performer`
name them: `et` (the Episodic Transformer, `agent.PerformerAgent`) and `map` (the map-and-plan
performer over the checkpoint's perception network, `mapper.agent.MapAgent`). No ROS."""

from __future__ import annotations

from pathlib import Path

PERFORMER_MODELS = ('et', 'map')


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

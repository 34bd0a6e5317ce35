"""The performer models by name: one registry that the performer node's `model` parameter, `launch
eval --agent/--performer`, the demo, the RL fine-tuning's `--model` and `reproduce`'s stage hashes all
read. No ROS.

A model is a `PerformerModel`: its name, what it is, how to load its policy from a checkpoint, the
camera it plays at, its shipped checkpoint and the source files that play it (relative to the
repository: a `reproduce` stage that plays the model is rerun when one of them changes). The two
built in: `et` (the Episodic Transformer, `agent.PerformerAgent`) and `map` (the map-and-plan performer
over the checkpoint's perception network, `mapper.agent.MapAgent`). Adding a model is its module plus
one `register(PerformerModel(...))` (docs/performer.md, "Adding a model").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from dialfred_sim.registry import Registry

from .checkpoint_header import HeaderError, read_header
from .shipped import SHIPPED_CHECKPOINT

# The map performer's camera: 128 px frames, area-averaged down to its network's input. Over
# the shipped et.pt's network (64 px), valid_unseen instruction only: 45.0 SR, against 41.7 with a camera
# of the network's own 64 px (an averaged frame keeps objects thinner than one of the network's pixels).
MAP_CAMERA = 128

_PERF = 'src/dialfred_performer/dialfred_performer'


@dataclass(frozen=True)
class PerformerModel:
    """A performer model. `load(path)`: its policy (a protocol.Agent) from checkpoint `path`;
    `camera(path)`: the frame size it plays at with that checkpoint. Both raise FileNotFoundError for a
    missing file and ValueError for one the model cannot use. `fixed_camera`: the frame size it plays at
    whatever the checkpoint, or None where that is the checkpoint's training resolution (so a pipeline that
    trains the checkpoint knows the camera before it exists)."""

    name: str
    description: str
    load: Callable[[Path], object]
    camera: Callable[[Path], int]
    checkpoint: Path
    sources: tuple[str, ...]
    fixed_camera: Optional[int] = None


PERFORMER_MODELS: Registry[PerformerModel] = Registry('performer model')


def register(model: PerformerModel) -> PerformerModel:
    """Add `model` to the registry (ValueError if its name is taken)."""
    return PERFORMER_MODELS.add(model.name, model)


def unregister(name: str) -> None:
    """Remove a model registered after the shipped ones (ValueError for an unknown name)."""
    PERFORMER_MODELS.remove(name)


def performer_model(name: str) -> PerformerModel:
    """The registered model `name` (ValueError naming the known ones otherwise)."""
    return PERFORMER_MODELS.named(name)


def load_policy(model: str, path: Path):
    """The policy of `model` from checkpoint `path`. FileNotFoundError when there is no file; ValueError
    (a CheckpointError among them) for an unknown model or a checkpoint the model cannot use."""
    return performer_model(model).load(Path(path))


def camera_resolution(model: str, path: Path) -> int:
    """The camera pixels `model` plays at with checkpoint `path`. FileNotFoundError / ValueError as load_policy."""
    return performer_model(model).camera(Path(path))


# ------------------------------------------------------------------------------ the built-in models
# Each loader imports its model's module when called: a node or an evaluation of one model does not
# import (and pay the start-up of) the other.

def _load_et(path: Path):
    from .agent import PerformerAgent  # lazy: pybullet, torch, which the rest of this module does without
    return PerformerAgent.from_checkpoint(path)


def _et_camera(path: Path) -> int:
    """The et performer's training resolution, read from its checkpoint (a frame of another size would be
    area-averaged, not the rendering it learned from): from the checkpoint's header, without torch
    (checkpoint_header.py); a file whose header cannot be read so is loaded whole, which says why."""
    try:
        return int(read_header(path)['config']['resolution'])
    except (HeaderError, KeyError, TypeError, ValueError):
        pass
    from .model import load_checkpoint  # lazy: pybullet, torch, which the rest of this module does without
    return int(load_checkpoint(path)[0].config.resolution)


def _load_map(path: Path):
    from .mapper.agent import MapAgent  # lazy: pybullet, torch, which the rest of this module does without
    return MapAgent.from_checkpoint(path)


ET_SOURCES = (f'{_PERF}/agent.py', f'{_PERF}/model_registry.py', f'{_PERF}/model.py', f'{_PERF}/preprocess.py',
              f'{_PERF}/perception.py',
              *(f'{_PERF}/nn/{name}.py' for name in ('enc_action', 'enc_lang', 'enc_perceived', 'enc_visual', 'enc_vl',
                                                      'heads')))
# The map performer is made from the E.T.'s checkpoint, so its code is the E.T.'s and the mapper's.
MAP_SOURCES = (*ET_SOURCES, *(f'{_PERF}/mapper/{name}.py' for name in ('agent', 'geometry', 'language', 'semantic_map',
                                                                     'wayfinding', 'reading', 'rules', 'sensing',
                                                                     'targets')))

register(PerformerModel('et', 'the Episodic Transformer performer of the checkpoint', _load_et, _et_camera,
                        SHIPPED_CHECKPOINT, ET_SOURCES))
register(PerformerModel('map', "the map-and-plan performer over the checkpoint's perception network "
                        '(dialfred_performer.mapper)', _load_map, lambda path: MAP_CAMERA, SHIPPED_CHECKPOINT,
                        MAP_SOURCES, fixed_camera=MAP_CAMERA))

"""The performer models' registry (dialfred_performer.model_registry): every consumer reads it.

Claims: the built-in models are `et` and `map`, each with its loader, camera, shipped checkpoint and the
source files that reproduce's stages hash (files that exist); the node's `model` parameter, `launch
eval --performer` and reproduce's MODEL_CODE list exactly the registry; an unknown name is refused
naming the known ones, a taken name cannot be registered twice; and a toy model registered by this
test alone (its module plus one `register`) is evaluated by name for one episode, through the graph,
with no other file touched.
"""

from __future__ import annotations

import pytest

from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.paths import REPO
from dialfred_bringup.reproduce.stages import MODEL_CODE
from dialfred_performer import node as performer_node
from dialfred_performer.model_registry import (MAP_CAMERA, PERFORMER_MODELS, SHIPPED_CHECKPOINT, PerformerModel,
                                       camera_resolution, load_policy, performer_model, register, unregister)


def test_the_built_in_models_and_every_consumer_read_the_registry():
    assert list(PERFORMER_MODELS) == ['et', 'map']
    assert camera_resolution('map', SHIPPED_CHECKPOINT) == MAP_CAMERA
    assert camera_resolution('et', SHIPPED_CHECKPOINT) == 64               # the shipped et.pt's training frames
    for model in PERFORMER_MODELS.values():
        assert model.checkpoint == SHIPPED_CHECKPOINT and model.sources
        assert all((REPO / f).is_file() for f in model.sources), model.name
    assert MODEL_CODE == {name: m.sources for name, m in PERFORMER_MODELS.items()}
    param = next(p for p in performer_node.PARAMETERS if p.name == 'model')
    assert tuple(param.choices) == tuple(PERFORMER_MODELS)
    with pytest.raises(ValueError, match='unknown performer model .nope.; expected one of et, map'):
        load_policy('nope', SHIPPED_CHECKPOINT)
    with pytest.raises(ValueError, match='registered already'):
        register(PerformerModel('et', 'again', lambda p: None, lambda p: 64, SHIPPED_CHECKPOINT, ()))


class StopAtOnce:
    """The toy model's policy: its first action is Stop."""

    name = 'toy'

    def reset(self, task, seed: int) -> None:
        pass

    def act(self, observation):
        return ('Stop', -1, -1)


def test_a_registered_toy_model_is_evaluated_by_name(tmp_path):
    register(PerformerModel('toy', 'stops at once (a test)', lambda path: StopAtOnce(), lambda path: 48,
                            SHIPPED_CHECKPOINT, ()))
    try:
        assert performer_model('toy').camera(SHIPPED_CHECKPOINT) == 48
        config = EvalConfig(split='valid_unseen', agent='toy', limit=1, workers=1, out=tmp_path / 'toy.jsonl')
        report = run_eval(config, progress=False)
    finally:
        unregister('toy')
    [result] = report.results
    assert result.agent.startswith('toy-') and result.end_reason == 'stop' and result.steps == 1
    assert config.resolution == 48                                         # the model's camera, from the registry

"""A config dataclass is its command line: every field type and option of dialfred_sim.dataclass_cli,
and every entry point of the launcher built with it."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pytest

from dialfred_sim.dataclass_cli import add_fields, arg, check_bounds, from_args, parse, parser_for, to_argv


def parse_pair(text: str) -> tuple:
    k, n = (int(p) for p in text.split('/'))
    if not 0 <= k < n:
        raise ValueError(f'a pair is K/N with 0 <= K < N, got {text!r}')
    return k, n


@dataclass
class Config:
    """A config of every kind of field."""

    split: str = arg('valid_unseen', 'a split', choices=['train', 'valid_unseen'], group='tasks')
    tasks_file: Optional[Path] = arg(None, 'a file instead', flag='--tasks', group='tasks')
    questioner: str = arg('', 'who asks', aliases={'none': ''})
    limit: Optional[int] = arg(None, 'tasks at most')
    pair: Optional[tuple] = arg(None, 'one of N', parse=parse_pair, show=lambda p: f'{p[0]}/{p[1]}')
    port: Optional[int] = arg(None, 'a port; the flag alone: 8765', const=8765)
    out: Path = arg(Path('out/x'), 'where to write')
    rate: float = arg(0.5, 'how often')
    local: bool = arg(False, 'no ROS')

    def __post_init__(self):
        if not 0 <= self.rate <= 1:
            raise ValueError(f'--rate must be in [0, 1], got {self.rate}')


def test_no_flags_give_the_dataclass_defaults():
    assert parse(Config, []) == Config()


def test_each_kind_of_field_reads_its_text():
    c = parse(Config, ['--tasks', 'a/b.jsonl', '--questioner', 'none', '--limit', '7', '--pair', '1/3',
                       '--port', '--out', 'o', '--rate', '0.25', '--local'])
    assert c == Config(tasks_file=Path('a/b.jsonl'), questioner='', limit=7, pair=(1, 3), port=8765,
                       out=Path('o'), rate=0.25, local=True)
    assert parse(Config, ['--port', '9000', '--limit', 'none']).port == 9000
    assert parse(Config, ['--limit', 'none']).limit is None
    assert parse(Config, ['--tasks', '']).tasks_file is None            # not Path(''), the current folder


@pytest.mark.parametrize('config', [Config(), Config(split='train', questioner='all', limit=3, pair=(0, 2), port=1,
                                                     out=Path('/tmp/o'), rate=1.0, local=True),
                                    Config(tasks_file=Path('t.jsonl'))])
def test_to_argv_rebuilds_the_config(config):
    argv = to_argv(config)
    assert parse(Config, argv) == config
    if config.tasks_file is None:
        assert '--split' in argv


@pytest.mark.parametrize('argv, said', [
    (['--split', 'valid_seen'], "'valid_seen' is not one of train, valid_unseen"),
    (['--split', 'valid_unseen', '--tasks', 'x'], 'not allowed with argument'),      # an interned default too
    (['--pair', '2/2'], 'a pair is K/N with 0 <= K < N'),
    (['--limit', 'many'], "invalid int value: 'many'"),
    (['--rate', '2'], r'--rate must be in \[0, 1\], got 2.0'),                         # __post_init__'s ValueError
    (['--out', ''], 'an empty path'),
])
def test_a_bad_value_is_a_usage_error_that_names_it(argv, said, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse(Config, argv)
    assert exit_info.value.code == 2
    import re
    assert re.search(said, capsys.readouterr().err)


def test_each_help_text_ends_with_its_default_as_the_command_line_writes_it():
    text = ' '.join(parser_for(Config).format_help().split())
    for expected in ('a split (default: valid_unseen)', 'who asks (default: none)', 'tasks at most (default: none)',
                     'how often (default: 0.5)', 'no ROS (default: --no-local)', '--split {train,valid_unseen}'):
        assert expected in text


def test_a_subparser_takes_the_fields_beside_options_of_its_own():
    parser = argparse.ArgumentParser()
    job = parser.add_subparsers(dest='command').add_parser('job')
    add_fields(Config, job)
    job.add_argument('--progress', action=argparse.BooleanOptionalAction, default=True)
    args = parser.parse_args(['job', '--limit', '2', '--no-progress'])
    assert from_args(Config, args, job) == Config(limit=2) and args.progress is False


def test_a_field_the_command_line_cannot_write_is_refused_when_the_parser_is_made():
    @dataclass
    class Bad:
        names: list = dataclasses.field(default_factory=list)

    with pytest.raises(TypeError, match='Bad.names'):
        parser_for(Bad)


# ------------------------------------------------------------------------------------------ the launcher


def launcher_parser():
    from dialfred_bringup.launch import make_parser
    return make_parser()


@pytest.mark.parametrize('job', ['demo', 'explore', 'nodes', 'dialogue', 'eval'])
def test_every_launcher_job_with_no_options_is_its_config_dataclass_defaults(job):
    from dialfred_bringup import launch
    from dialfred_bringup.evaluation import EvalConfig, eval_config
    args = launcher_parser().parse_args([job])
    if job == 'eval':
        assert eval_config(args) == EvalConfig() and args.progress is True
    else:
        config_class, _ = launch.JOBS[job]
        assert from_args(config_class, args, args.config_parser) == config_class()


def test_an_eval_config_round_trips_through_the_launcher_command_line(tmp_path):
    from dialfred_bringup.evaluation import EvalConfig, eval_config
    config = EvalConfig(split='valid_seen', agent='random', questioner='all', perturb_type='location',
                        perturb_probability=0.25, limit=5, shard=(1, 3), workers=1, out=tmp_path / 'r.jsonl', seed=4,
                        resolution=96, max_restarts=0, record=tmp_path / 'bags', record_format='png', foxglove=9000,
                        request_timeout=30.0)
    assert eval_config(launcher_parser().parse_args(['eval', *to_argv(config)])) == config


def test_the_et_performer_defaults_to_its_checkpoints_resolution_the_map_performer_and_others_to_128():
    from dialfred_bringup.evaluation import EvalConfig
    from dialfred_sim.env import DEFAULT_RESOLUTION
    from dialfred_performer.model import SHIPPED_CHECKPOINT, load_checkpoint
    shipped = int(load_checkpoint(SHIPPED_CHECKPOINT)[0].config.resolution)
    assert EvalConfig(agent='et').resolution == shipped == EvalConfig(performer='et').resolution
    assert EvalConfig(agent='random').resolution == DEFAULT_RESOLUTION == 128
    assert EvalConfig(agent='et', resolution=32).resolution == 32
    # the map performer plays at its own camera (128 px, area-averaged to its 64 px network), whatever file
    from dialfred_performer.model_registry import MAP_CAMERA
    assert EvalConfig(agent='map').resolution == EvalConfig(performer='map').resolution == MAP_CAMERA == 128
    assert EvalConfig(agent='map', checkpoint=SHIPPED_CHECKPOINT).resolution == MAP_CAMERA


def test_the_option_tables_of_the_docs_are_made_from_the_dataclasses():
    import subprocess
    import sys
    from dialfred_bringup.paths import REPO
    done = subprocess.run([sys.executable, 'scripts/doc_options.py', '--check'], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    assert '<!-- options: dialfred_bringup.eval_config:EvalConfig -->' in (REPO / 'docs' / 'evaluation.md').read_text()
    assert '| `--limit N` | only the first N tasks of the split (none: all) | `none` |' in (
        REPO / 'docs' / 'evaluation.md').read_text()


def test_a_resume_counts_a_field_its_saved_config_lacks_as_the_default():
    from dialfred_sim.dataclass_cli import config_changes
    from dialfred_questioner.finetune import FinetuneConfig
    cfg = FinetuneConfig(init='a.pt', out='o')
    saved = dataclasses.asdict(cfg)
    del saved['model']                                   # a run started before --model existed
    assert config_changes(saved, cfg, ()) == {}
    other = FinetuneConfig(init='a.pt', out='o', model='map')
    assert config_changes(saved, other, ()) == {'model': ('et', 'map')}
    assert config_changes({**saved, 'lr': 0.5}, cfg, ('lr',)) == {}


def test_check_bounds_names_the_first_field_out_of_its_bounds():
    @dataclasses.dataclass
    class Bounded:
        workers: int = 2
        seed: int = 0
        lr: float = 1e-3
        share: float = 0.5

    check_bounds(Bounded(), at_least_one=('workers',), non_negative=('seed',), positive=('lr',), fractions=('share',))
    for changed, message in (({'workers': 0}, 'workers must be at least 1, got 0'),
                             ({'seed': -1}, 'seed must be >= 0, got -1'),
                             ({'lr': float('nan')}, 'lr must be a positive number, got nan'),
                             ({'lr': 0.0}, 'lr must be a positive number, got 0.0'),
                             ({'share': 1.5}, r'share must be in \[0, 1\], got 1.5')):
        with pytest.raises(ValueError, match=message):
            check_bounds(Bounded(**changed), at_least_one=('workers',), non_negative=('seed',), positive=('lr',),
                         fractions=('share',))

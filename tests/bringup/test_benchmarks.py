"""Every benchmark script runs end to end on a tiny budget and prints the JSON its docs quote.

The figures themselves are measured on a quiet machine (docs/figures.md); these smoke tests only
keep the scripts working, so that `./dialfred bench NAME` does not rot between measurements.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def run_bench(name: str, *args: str, timeout: float = 240) -> dict:
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / f'{name}.py'), *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = proc.stdout
    return json.loads(out[out.index('{'):])   # pybullet prints a banner line first


@pytest.mark.slow   # a benchmark script end to end; culled frames equal full draws: tests/sim/test_culling.py
def test_render_culling_times_both_draws_and_finds_the_same_frames_and_files():
    report = run_bench('render_culling', '--tasks', '2', '--resolutions', '64', '--demos', '3', '--rounds', '1')
    row = report['resolutions']['64']
    assert row['frames'] > 2 and row['differing_frames'] == 0
    assert row['ms_per_render_off'] > 0 and row['ms_per_render_on'] > 0 and row['hidden_objects_mean'] > 0
    assert report['demos']['tasks'] == 3 and report['demos']['same_files'] is True


def test_sim_step_reports_the_overhead_over_the_bare_render():
    # 20 steps: at 64 px a render takes about 2 ms, so one stall of a loaded machine in 5 steps could double
    # the bare mean (seen once: 2.02)
    report = run_bench('sim_step', '--steps', '20', '--rounds', '1', '--resolutions', '64')
    row = report['results']['64x64']
    assert row['step_ms'] > 0 and row['bare_render_ms'] > 0
    assert 0 < row['ratio_bare_over_step'] <= 2


def test_import_weight_tells_a_light_module_from_one_that_loads_torch():
    report = run_bench('import_weight', '--modules', 'dialfred_sim.protocol', 'dialfred_oracle.answers',
                       'dialfred_performer.nn.heads')
    assert report['modules']['dialfred_sim.protocol']['heavy'] == []
    assert report['light_modules'] == ['dialfred_oracle.answers', 'dialfred_sim.protocol']
    assert 'torch' in report['modules']['dialfred_performer.nn.heads']['heavy'] and report['modules_loading']['torch'] == 1
    assert report['errors'] == [] and report['imports_inside_functions'] >= 0
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'import_weight.py'), '--modules', 'no.such'],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and 'not a module of src/: no.such' in proc.stderr


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_ros_step_reports_both_reply_forms_and_the_ros_floor():
    report = run_bench('ros_step', '--resolution', '64', '--steps', '6')
    for label in ('rgb_depth_segmentation', 'rgb_only', 'floor_empty_trigger'):
        part = report[label]
        assert part['ros_round_trip']['median_ms'] > 0 and part['in_process']['median_ms'] > 0
        assert 'added_by_ros_paired_median_ms' in part
    assert report['rgb_only']['sim_node_peak_rss_mb'] > 50


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_oracle_latency_times_both_paths_and_answers_every_request():
    report = run_bench('oracle_latency', '--requests', '30', '--after-steps', '3')
    assert set(report['paths']) == {'fetch_every_question', 'cached'}
    for path in report['paths'].values():
        for group in ('location_direction', 'appearance'):
            assert path[group]['invalid_replies'] == 0
            assert path[group]['one_at_a_time']['requests_per_s'] > 0 and path[group]['pipelined']['requests_per_s'] > 0
        assert path['location_after_a_step']['p50_ms'] > 0
    assert isinstance(report['goal']['met'], bool)


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_service_flood_answers_every_request_only_with_keep_all():
    report = run_bench('service_flood', '--steps', '60', '--questions', '40', '--wait', '5')
    for service, sent in (('sim_step', 60), ('oracle_answer', 40)):
        assert report['keep_all'][service]['replied'] == report['keep_all'][service]['ok'] == sent
        assert report['ros_default'][service]['replied'] < sent     # the baseline loses some: it is a real baseline


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_oracle_fuzz_finds_no_crash_on_a_short_run():
    report = run_bench('oracle_fuzz', '--requests', '60')
    assert report['crashes'] == 0 and report['malformed_replies'] == 0 and report['oracle_alive_at_end']
    assert report['passed'] is True


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_oracle_correctness_scores_every_question_kind():
    report = run_bench('oracle_correctness', '--questions', '12')
    assert report['questions'] == 12
    assert report['location_receptacle']['n'] > 0 and report['appearance_colour']['n'] > 0


@pytest.mark.parametrize('workers', [1, 2])
@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_expert_replay_succeeds_on_the_first_tasks(workers):
    report = run_bench('expert_replay', '--limit', '4', '--workers', str(workers))
    assert report['tasks'] == 4 and report['success_rate'] == 100.0 and report['failures'] == []


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_expert_gc_finds_gc_starting_at_0_and_never_falling_on_the_first_tasks():
    report = run_bench('expert_gc', '--limit', '12')
    assert report['tasks'] == 12 and report['expert_failures'] == []
    assert report['gc_nonzero_or_nothing_to_do_at_start'] == [] and report['falls'] == []
    assert sum(row['n'] for row in report['per_type'].values()) == 12


def test_question_worth_divides_the_sr_gained_by_the_questions_asked(tmp_path):
    from dialfred_sim.metrics import EpisodeResult, append_result
    rows = [('valid_unseen/000000', 'Move', False, True, 2), ('valid_unseen/000001', 'Move & Pick', False, False, 4),
            ('valid_unseen/000002', 'Put', True, True, 2), ('valid_unseen/000003', 'Close', False, True, 0)]
    for task_id, task_type, before, after, questions in rows:
        common = dict(task_id=task_id, task_type=task_type, split='valid_unseen', goal_conditions_met=0,
                      goal_conditions_total=1, steps=5, expert_length=5, goal_rule='dialfred')
        append_result(tmp_path / 'none.jsonl', EpisodeResult(success=before, agent='et', **common))
        append_result(tmp_path / 'all.jsonl', EpisodeResult(success=after, questions=questions, agent='et+all', **common))
    report = run_bench('question_worth', '--base', str(tmp_path / 'none.jsonl'), '--asked', str(tmp_path / 'all.jsonl'))
    groups = report['groups']
    assert groups['overall'] == {'n': 4, 'SR_without': 25.0, 'SR_with': 75.0, 'NQ': 2.0, 'worth': 25.0}
    assert groups['family: with a go-to']['worth'] == pytest.approx(50.0 / 3.0, abs=1e-3)
    assert groups['family: without a go-to']['worth'] == 50.0 and groups['type: Close']['NQ'] == 0.0
    assert report['paper_worth'] == pytest.approx(4.228, abs=1e-3)


def test_world_statistics_puts_each_figure_beside_ai2thors():
    report = run_bench('world_statistics', '--episodes', '3')
    assert report['episodes'] == 3 and report['tasks'] > 0
    assert set(report['rooms']) == {'kitchen', 'living_room', 'bedroom', 'bathroom'}
    for room in report['rooms'].values():
        for key in ('navigable_points', 'receptacles', 'openable_fixtures'):
            fig = room[key]
            assert fig['value'] > 0 and fig['ratio'] == pytest.approx(fig['value'] / fig['reference'], abs=1e-3)
    split = report['per_split']
    assert split['goto_actions']['value'] == pytest.approx(
        split['goto_moves']['value'] + split['goto_turns']['value'] + split['goto_looks']['value'], abs=0.01)
    assert 0 <= split['first_target_in_closed']['value'] <= 1 and split['first_target_distance_m']['reference'] == 2.67
    assert 'reference' not in split['target_visible_at_task_start']


@pytest.mark.slow   # the bench end to end (12 s); its pose arithmetic is tested fast below
def test_expert_poses_replays_the_shipped_episodes_and_counts_the_go_tos_that_end_elsewhere():
    # the first 6 valid_unseen episodes: 9 go-tos before a put, 3 of which end past the plain pose (one of
    # them a fridge's, 5 actions away)
    report = run_bench('expert_poses', '--episodes', '6')
    assert report['episodes'] == 6 == report['same_as_shipped']
    assert report['gotos_checked'] == report['gotos_checked_put'] + report['gotos_checked_inside'] > 0
    assert 0 < report['elsewhere'] <= report['gotos_checked']
    assert sum(report['gap_actions'].values()) + report['no_plain_pose'] == report['elsewhere']
    assert report['elsewhere_beyond_4_actions_at_least'] == sum(v for k, v in report['gap_actions'].items() if int(k) > 4)
    assert sum(report['elsewhere_by_type'].values()) == report['elsewhere']


def test_the_gap_between_two_poses_counts_steps_turns_and_looks():
    import importlib.util     # inline: the bench is a script, not a module of a package
    spec = importlib.util.spec_from_file_location('expert_poses', REPO / 'benchmarks' / 'expert_poses.py')
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    gap_actions = bench.gap_actions
    assert gap_actions((3, 4, 90, 30.0), (3, 4, 90, 30.0)) == 0
    assert gap_actions((3, 4, 0, 30.0), (5, 3, 270, 0.0)) == 3 + 1 + 2       # 3 steps, a quarter turn, 2 looks
    assert gap_actions((0, 0, 0, 0.0), (0, 0, 180, 0.0)) == 2


def test_world_statistics_reads_a_split_file_of_ones_own(tmp_path):
    from dialfred_sim.tasks.splits import write_split
    path = tmp_path / 'sealed.jsonl.gz'
    write_split('test_unseen', path, size=4, split_seed=11, progress=False)
    report = run_bench('world_statistics', '--file', str(path))
    assert report['split'] == 'test_unseen' and report['file']['tasks'] == 4 == report['tasks']
    assert report['file']['path'] == str(path) and len(report['file']['sha256']) == 64
    assert report['per_split']['gotos'] >= 0 and report['per_split']['goto_looks']['reference'] == 1.85
    missing = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'world_statistics.py'), '--file',
                              str(tmp_path / 'none.jsonl.gz')], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert missing.returncode == 2 and 'does not exist' in missing.stderr


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_split_physics_finds_every_shipped_valid_episode_allowed():
    report = run_bench('split_physics', '--split', 'valid_unseen', '--limit', '6')
    assert report['episodes'] == 6 and report['tasks'] > 0
    assert report['episodes_refused'] == 0 and report['refused'] == [] and report['reasons'] == {}


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_recording_reports_the_overhead_and_the_bag_size_per_episode():
    report = run_bench('recording', '--limit', '2', '--rounds', '1', '--workers', '1', '--settings', 'off', 'png')
    png = report['settings']['png']
    assert report['same_episodes_in_every_run'] and png['episodes'] == 2
    assert png['bytes_per_episode'] > 1000 and 'overhead_pct' in png and png['kB_per_frame'] > 0


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_bench_scaling_reports_throughput_by_workers_and_the_cost_on_n_machines(tmp_path):
    png = tmp_path / 'scaling.png'
    report = run_bench('bench_scaling', '--workers', '1', '2', '--limit', '3', '--resolution', '64',
                       '--machines', '1', '4', '--plot', str(png))
    assert [r['workers'] for r in report['by_workers']] == [1, 2]
    for row in report['by_workers']:
        assert row['episodes'] == 3 and row['episodes_per_s'] > 0 and row['startup_s'] > 0
        assert row['s_per_task'] == pytest.approx(1 / row['episodes_per_s'], rel=1e-3)
    assert report['by_workers'][0]['speedup'] == 1.0
    best = max(report['by_workers'], key=lambda r: r['episodes_per_s'])
    one, four = report['cost']['table']
    assert (one['machines'], one['tasks_per_machine'], four['tasks_per_machine']) == (1, 1000, 250)
    assert one['wall_min'] * 60 == pytest.approx(best['startup_s'] + 1000 * best['s_per_task'], abs=1)
    assert four['wall_min'] < one['wall_min']
    from PIL import Image
    assert Image.open(png).size[0] > 600


def test_bench_scaling_rejects_a_bad_budget():
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'bench_scaling.py'), '--workers', '0'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and '--workers must be integers >= 1' in proc.stderr


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_training_determinism_compares_fresh_processes_update_by_update(tmp_path):
    from dialfred_performer.prepare import PrepareConfig, prepare
    folder = tmp_path / 'valid_unseen_64'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=3, out=str(folder), progress=False))
    report = run_bench('training_determinism', '--tiny', '--runs', '2', '--updates', '3', '--threads', '1',
                       '--demonstrations', str(folder), '--env', 'MKL_DYNAMIC=FALSE', '--busy', '1')
    assert report['runs'] == 2 and report['env'] == {'MKL_DYNAMIC': 'FALSE'} and report['busy'] == 1
    (other,) = report['against_run_1']
    assert other['updates'] == 3 and other['busy_beside'] == 1      # run 2 had a busy process beside it
    assert report['runs_with_common_stream'] == 2 and len(report['common_stream_sha256']) == 64
    # one thread, a tiny model, the same seed: the two processes agree bit for bit
    assert report['identical'] and other['first_different_update'] is None and other['max_relative_difference'] == 0


def test_training_determinism_rejects_a_malformed_env():
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'training_determinism.py'), '--env', 'NOEQUALS'],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and 'VAR=VALUE' in proc.stderr


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests of its own
def test_eval_local_times_every_path_and_finds_the_same_episodes():
    report = run_bench('eval_local', '--limit', '3', '--questioner', 'all')
    assert report['same_episodes'] is True and report['NQ'] > 0
    assert set(report['wall_s_best']) == {'local', 'in-process', 'graph'}
    assert set(report['speedup_of_local']) == {'in-process', 'graph'}


@pytest.mark.slow   # a benchmark script end to end; what it measures has fast tests (test_silent)
def test_silent_replay_replays_the_silent_episodes_and_finds_the_same_ones():
    report = run_bench('silent_replay', '--limit', '6', '--workers', '1', '--questioner', 'random')
    assert report['same_episodes'] is True and report['replayed'] == report['silent_episodes']
    assert set(report['wall_s']) == {'alone_recorded', 'questioner_played', 'questioner_replayed'}


@pytest.mark.slow   # a benchmark script end to end; the map performer has fast tests of its own
def test_map_decision_times_real_steps():
    report = run_bench('map_decision', '--tasks', '1', '--signal')
    assert report['steps'] >= 1 and 0 < report['ms_median'] <= report['ms_max'] and report['signal']


@pytest.mark.slow   # a benchmark script end to end
def test_perception_recall_counts_objects_and_what_it_found():
    report = run_bench('perception_recall', '--every', '400', '--resolution', '64')
    row = report['recall']['64']['all']
    assert row['objects'] >= 1 and 0 <= row['found'] <= row['objects']


@pytest.mark.slow   # a benchmark script end to end (replays two map performer episodes)
def test_map_pickup_failures_classifies_replayed_failures(tmp_path):
    from dialfred_sim.tasks.split_files import load_split
    picks = [t for t in load_split('valid_unseen') if t.task_type == 'Pick'][:2]
    # a synthetic results file: two Pick tasks recorded as failed, for the benchmark to replay
    row = dict(split='valid_unseen', success=False, goal_conditions_met=0, goal_conditions_total=1, steps=1,
               expert_length=1, questions=0, failed_actions=0, invalid_questions=0, end_reason='stop', error='',
               agent='map-test', oracle='', seed=0, wall_s=0.0, privileged=False, dialogue=[])
    results = tmp_path / 'results.jsonl'
    results.write_text(''.join(json.dumps({**row, 'task_id': t.task_id, 'task_type': t.task_type}) + '\n'
                               for t in picks))
    report = run_bench('map_pickup_failures', str(results), '--questioner', 'none', '--limit', '2', timeout=400)
    assert report['episodes'] == 2 and sum(report['classes'].values()) == 2
    assert set(report['classes']) <= {'never_near', 'near_never_labelled', 'labelled'}
    assert {e['task_id'] for e in report['by_episode']} == {t.task_id for t in picks}


@pytest.mark.slow   # a benchmark script end to end; chunked scoring equals one batch: test_questioner_model.py
def test_rl_update_times_both_ways_of_scoring_and_finds_the_same_numbers():
    report = run_bench('rl_update', '--long', '12', '--repeats', '1', '--threads', '1')
    assert report['synthetic'] is True and report['decisions'] == 63 * 8 + 12
    assert report['seconds_one_batch'] > 0 and report['seconds_chunked'] > 0
    assert report['max_abs_difference'] < 1e-4


@pytest.mark.slow   # a benchmark script end to end (eight short map performer episodes)
def test_map_perception_ceiling_plays_both_sights_with_and_without_questions(tmp_path):
    report = run_bench('map_perception_ceiling', '--limit', '8', '--shard', '0/4', '--out', str(tmp_path),
                       '--no-progress', timeout=400)
    assert set(report['settings']) == {'network/none', 'network/all', 'truth/none', 'truth/all'}
    assert all(s['n'] == 2 for s in report['settings'].values())
    assert report['settings']['network/all']['NQ'] > 0 == report['settings']['network/none']['NQ']
    truth = [json.loads(line) for line in (tmp_path / 'truth_all.jsonl').read_text().splitlines()]
    assert all(r['privileged'] and r['agent'].endswith('+truth-sight') for r in truth)
    again = run_bench('map_perception_ceiling', '--limit', '8', '--shard', '0/4', '--out', str(tmp_path),
                      '--no-progress')     # resumed: nothing left to play, the same report
    assert again['settings'] == report['settings']


@pytest.mark.slow   # a labelled slice rendered and a perception network trained first
def test_performer_update_times_each_piece_in_random_and_block_order(tmp_path):
    from dialfred_performer.perception import main as perception_main
    from dialfred_performer.prepare import PrepareConfig, prepare
    demos, perception = tmp_path / 'demos', tmp_path / 'perception'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=10, out=str(demos), progress=False,
                          labels=True))
    assert perception_main(['--demonstrations', str(demos), '--out', str(perception), '--frames', '32',
                            '--batch-size', '16', '--val-frames', '16', '--val-fraction', '0.3', '--no-progress', '--c1', '8', '--c2', '8',
                            '--c3', '16', '--decoder', '8']) == 0
    args = ('--perception', str(perception / 'perception.pt'), '--demonstrations', str(demos), '--updates', '2',
            '--skip', '0', '--threads', '1', '--batch-size', '8')
    random, blocks = run_bench('performer_update', *args), run_bench('performer_update', *args, '--block-tasks', '4')
    # Every batch of the epoch timed: the sample's frames per update are the epoch's.
    whole = run_bench('performer_update', *args[:4], '--updates', '1000', '--skip', '0', '--threads', '1',
                      '--batch-size', '8')
    assert whole['frames_per_update'] == pytest.approx(whole['epoch_frames_per_update'], abs=0.1)
    for report in (random, blocks):
        pieces = report['seconds_per_update']
        assert report['updates_timed'] >= 1 and pieces['update'] > 0
        assert sum(v for k, v in pieces.items() if k != 'update') == pytest.approx(pieces['update'], rel=0.05, abs=1e-3)
        # The stage's estimate: the sample's seconds per frame at the epoch's mean frames per update.
        per_frame = report['seconds_per_update_at_epoch_mean'] / report['epoch_frames_per_update']
        assert report['epoch_frames_per_update'] > 1
        assert per_frame == pytest.approx(1 / report['frames_per_s'], rel=0.02)
    assert random['seconds_per_update']['frozen_network'] > 0 and random['block_load_s'] == 0
    assert blocks['seconds_per_update']['frozen_network'] == 0 < blocks['block_load_s']     # run once, at the block's start
    assert blocks['block_batches'] >= 1


@pytest.mark.slow   # a benchmark script end to end; the layouts' equal outputs have a fast test (test_perception)
def test_perception_layout_times_both_layouts_and_finds_the_same_outputs_up_to_rounding():
    report = run_bench('perception_layout', '--steps', '1', '--skip', '0', '--batch', '4', '--forward-batch', '4',
                       '--threads', '1', '--rounds', '2')
    assert report['rounds'] == 2
    for layout in ('nchw', 'nhwc'):
        row = report[layout]
        assert row['train_step_s'] > 0 and row['forward_4_s'] > 0 and row['forward_1_frame_1_thread_ms'] > 0
    assert report['data'] == 'synthetic' and set(report['speedup']) == {'train_step_s', 'forward_4_s',
                                                                        'forward_1_frame_1_thread_ms'}
    assert 0 <= report['max_abs_output_difference'] < 1e-3


def test_perception_layout_refuses_a_bad_budget():
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'perception_layout.py'), '--steps', '0'],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and '--steps must be at least 1' in proc.stderr


@pytest.mark.slow   # a benchmark script end to end: three fresh torch processes training; its digests speak across machines
def test_cpu_arithmetic_gives_each_mode_a_digest_that_repeats():
    first = run_bench('cpu_arithmetic', '--tiny', '--updates', '2', '--modes', 'native,avx2')
    again = run_bench('cpu_arithmetic', '--tiny', '--updates', '2', '--modes', 'native')
    assert set(first['modes']) == {'native', 'avx2'} and first['data'].startswith('synthetic')
    assert first['modes']['avx2']['env']['ATEN_CPU_CAPABILITY'] == 'avx2'
    assert first['same_weights_as_native']['native'] is True
    # a fresh process in the same mode trains the same weights
    assert again['modes']['native']['weights_sha256'] == first['modes']['native']['weights_sha256']


def test_cpu_arithmetic_refuses_an_unknown_mode():
    proc = subprocess.run([sys.executable, str(REPO / 'benchmarks' / 'cpu_arithmetic.py'), '--modes', 'fast'],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and 'unknown mode' in proc.stderr


@pytest.mark.slow   # a benchmark script end to end; the chained protocol has fast tests of its own
def test_chained_cost_plays_both_protocols_and_reports_their_ratio():
    report = run_bench('chained_cost', '--limit', '12', '--agents', 'expert', '--workers', '1')
    row = report['agents']['expert']
    assert row['expert']['SR'] == 100.0 and row['chained']['SR'] == 100.0
    assert row['chained']['actions_per_task'] >= row['expert']['actions_per_task']    # the stretch and a Stop
    assert row['ratio_chained_over_expert']['s_per_task'] > 0


@pytest.mark.slow   # a benchmark script end to end; the answerers have fast tests: tests/oracle/test_answerers.py
def test_answer_wording_plays_the_oracles_words_and_an_answerers_on_the_same_tasks(tmp_path):
    report = run_bench('answer_wording', '--limit', '4', '--agents', 'et', '--workers', '1', '--base',
                       '--out', str(tmp_path))
    row = report['agents']['et']
    assert row['tasks'] == 4 and row['oracle']['NQ'] == row['answerer']['NQ'] > 0
    assert row['instruction only']['NQ'] == 0
    lo, hi = row['SR_lost_to_wording_95']
    assert lo <= row['SR_lost_to_wording'] <= hi
    assert 0 < row['answer_words']['share_not_in_templates'] < 1
    assert len(list(tmp_path.glob('*_answers-dialfred_oracle.wording.HeldOutWording.jsonl'))) == 1


@pytest.mark.slow   # a benchmark script end to end; the reader has fast tests: tests/performer/test_mapper.py
def test_answer_reading_reads_the_templates_whole_and_scores_every_wording_source():
    report = run_bench('answer_reading', '--limit', '6')
    rows = report['sources']
    assert rows['templates']['types']['all']['recall'] == 1.0 == rows['templates']['types']['all']['precision']
    for source in ('annotator', 'held-out'):
        row = rows[source]['types']['all']
        assert row['answers'] == rows['templates']['types']['all']['answers'] > 10
        assert 0 < row['recall'] <= 1 and row['right'] <= row['read']
        assert row['right_said'] <= row['truth_said'] <= row['truth'] and row['recall_said'] >= row['recall']


@pytest.mark.slow   # two evaluations end to end
def test_direction_following_plays_the_blind_follower_and_a_performer_asked_before_every_action(tmp_path):
    report = run_bench('direction_following', '--agents', 'follower', 'et', '--limit', '4', '--out', str(tmp_path),
                       '--no-progress')
    follower, et = report['agents']['follower']['every_step'], report['agents']['et']
    assert follower['tasks'] == 4 and follower['NQ'] > 1                 # asked before every action
    assert et['every_step']['NQ'] > 1 and et['none']['NQ'] == 0
    assert et['move_SR_gain'] == (None if et['none']['move_SR'] is None else
                                  round(et['every_step']['move_SR'] - et['none']['move_SR'], 2))
    assert set(report['beats_the_blind_follower_on_move']) <= {'et'}
    obeyed = report['agents']['follower']['obeyed']       # it does what it hears, but where a move is blocked
    assert obeyed['steps'] > 0 and obeyed['share'] >= 0.8 and 0 <= report['agents']['et']['obeyed']['share'] <= 1
    assert len([p for p in tmp_path.glob('*.jsonl') if not p.name.endswith('.trace.jsonl')]) == 3   # one per run


@pytest.mark.slow   # a small guided build, then the benchmark script
def test_direction_agreement_counts_the_guided_walks_apart_and_they_obey(tmp_path):
    from dialfred_performer.prepare import PrepareConfig, prepare
    prepare(PrepareConfig(split='valid_unseen', resolution=32, workers=1, limit=4, out=str(tmp_path / 'g'),
                          progress=False, guided=True))
    report = run_bench('direction_agreement', '--demonstrations', str(tmp_path / 'g'))
    assert report['tasks'] == 4 and report['walk']['steps'] > 0 and report['expert']['steps'] > 0
    assert report['walk']['obeyed'] >= 0.8
    for part in ('expert', 'walk'):
        assert sum(row['steps'] for row in report[part]['answers'].values()) == report[part]['steps']

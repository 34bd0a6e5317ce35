"""Episode bags (dialfred_sim.bag), without a graph: SYNTHETIC episodes (random frames, made-up
QAs) written as rosbag2/MCAP bags and read back.

Claims: a bag read with an independent reader (the `mcap` library and mcap_ros2's decoder, not
rosbags which wrote it) has the expected topics, types, message counts and simulator-clock timestamps;
rclpy itself decodes each message's bytes into the same values (CDR's padding bytes may differ), and each type's hash
is the one rosidl generated for dialfred_msgs; the same episode gives the same bytes twice; PNG
frames come back exact; `replay` prints the dialogue and renders a GIF and a contact sheet; a
truncated or foreign bag is a clear error; bad input to the recorder is refused.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dialfred_bringup.replay import main as replay_main
from dialfred_bringup.replay import transcript
from dialfred_sim.bag import (ACTION_NS, QA_NS, RESULT_NS, STEP_NS, TOPICS, BagError, EpisodeRecorder, read_bag, read_episode,
                              typestore)

TASK = dict(task_id='valid_unseen/000007', scene='FloorPlan301', split='valid_unseen',
            instruction='Put the book on the bed.', object_nouns=['book', 'bed'])


def synthetic_episode(image_format: str = 'raw', seed: int = 0) -> tuple[EpisodeRecorder, list]:
    """Three actions, two QAs before the first and one before the third; random frames (SYNTHETIC)."""
    rng = np.random.default_rng(seed)
    frames = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in range(4)]
    rec = EpisodeRecorder(**TASK, image_format=image_format)
    rec.observation(0, frames[0], (1.0, 2.0, 90.0, 0.0), 0.9)
    rec.question(0, 'location', 'book', 'Where is the book?', 'The book is on the desk.', True)
    rec.question(0, 'appearance', 'unicorn', 'What does the unicorn look like?', '', False)
    rec.action(1, 'MoveAhead', -1, -1, True, 2)
    rec.observation(1, frames[1], (1.25, 2.0, 90.0, 0.0), 0.9)
    rec.action(2, 'RotateLeft', -1, -1, True, 2)
    rec.observation(2, frames[2], (1.25, 2.0, 180.0, 0.0), 0.9)
    rec.question(2, 'direction', '', 'Which way should I go?', 'Turn left.', True)
    rec.action(3, 'Pickup', 31, 20, False, 3)
    rec.observation(3, frames[3], (1.25, 2.0, 180.0, 0.0), 0.9)
    rec.result(success=False, steps=3, goal_conditions_met=0, goal_conditions_total=2, failed_actions=1,
               questions=3, invalid_questions=1, end_reason='max_steps', error='nothing there', last_action='Pickup')
    return rec, frames


def independent_read(bag: Path) -> list:
    """(topic, schema name, log time, decoded message) with the mcap library alone."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    (mcap_file,) = bag.glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(ch.topic, schema.name, msg.log_time, decoded)
                for schema, ch, msg, decoded in reader.iter_decoded_messages(log_time_order=True)]


def test_an_independent_reader_sees_every_message_with_its_type_and_sim_clock_time(tmp_path):
    rec, frames = synthetic_episode()
    bag = rec.save(tmp_path)
    assert bag == tmp_path / 'valid_unseen_000007' and (bag / 'metadata.yaml').is_file()
    rows = independent_read(bag)
    counts = {}
    for topic, schema, _, _ in rows:
        counts[topic] = counts.get(topic, 0) + 1
        assert schema == TOPICS[topic]
    assert counts == {'/task': 1, '/camera/image': 4, '/agent/pose': 4, '/agent/pose_stamped': 4,
                      '/dialogue/qa': 3, '/performer/action': 3, '/performer/feedback': 3, '/episode/result': 1}
    times = [t for _, _, t, _ in rows]
    assert times == sorted(times)
    by_topic = lambda topic: [(t, m) for tp, _, t, m in rows if tp == topic]
    assert [t for t, _ in by_topic('/camera/image')] == [k * STEP_NS for k in range(4)]
    assert [t for t, _ in by_topic('/dialogue/qa')] == [QA_NS, 2 * QA_NS, 2 * STEP_NS + QA_NS]
    assert [t for t, _ in by_topic('/performer/action')] == [k * STEP_NS + ACTION_NS for k in range(3)]
    assert [t for t, _ in by_topic('/episode/result')] == [3 * STEP_NS + RESULT_NS]
    t, image = by_topic('/camera/image')[2]
    assert (image.height, image.width, image.encoding, image.header.frame_id) == (48, 64, 'rgb8', 'agent_camera')
    assert image.header.stamp.sec * 10**9 + image.header.stamp.nanosec == t
    assert np.array_equal(np.frombuffer(bytes(image.data), np.uint8).reshape(48, 64, 3), frames[2])
    qa = by_topic('/dialogue/qa')[1][1]
    assert (qa.question_type, qa.object_noun, qa.valid, qa.answer) == ('appearance', 'unicorn', False, '')
    fb = by_topic('/performer/feedback')[2][1]
    assert (fb.step, fb.action.action, fb.action.x, fb.action.y, fb.action_success, fb.questions) == \
        (3, 'Pickup', 31, 20, False, 3)
    task = by_topic('/task')[0][1]
    assert (task.task_id, list(task.object_nouns)) == (TASK['task_id'], TASK['object_nouns'])


def same_fields(ros, ours) -> bool:
    """An rclpy message and a rosbags one hold the same values, field by field (nested, arrays)."""
    if hasattr(ros, 'get_fields_and_field_types'):
        return all(same_fields(getattr(ros, name), getattr(ours, name)) for name in ros.get_fields_and_field_types())
    if isinstance(ros, (str, bool, int, float)):
        return ros == ours
    return len(ros) == len(ours) and all(same_fields(a, b) for a, b in zip(ros, ours))


def test_rclpy_decodes_every_message_and_type_hashes_are_rosidls(tmp_path):
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message, serialize_message

    from dialfred_msgs.action import RunTask
    from dialfred_msgs.msg import Action, AgentPose, QAPair, TaskDescription
    from sensor_msgs.msg import Image
    bag = synthetic_episode()[0].save(tmp_path)
    classes = {'dialfred_msgs/msg/TaskDescription': TaskDescription, 'dialfred_msgs/msg/QAPair': QAPair,
               'dialfred_msgs/msg/AgentPose': AgentPose, 'dialfred_msgs/msg/Action': Action,
               'sensor_msgs/msg/Image': Image, 'dialfred_msgs/action/RunTask_Feedback': RunTask.Feedback,
               'dialfred_msgs/action/RunTask_Result': RunTask.Result}
    checked = set()
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        for schema, _channel, message in make_reader(f).iter_messages():
            cls = classes.get(schema.name)
            if cls is None:
                continue
            msg = deserialize_message(message.data, cls)                # rclpy reads our bytes ...
            ours = typestore().deserialize_cdr(message.data, schema.name)
            assert same_fields(msg, ours), schema.name                   # ... as the message we wrote
            again = serialize_message(msg)                               # and its bytes read back the same
            assert same_fields(deserialize_message(again, cls), ours) and len(again) == len(message.data)
            checked.add(schema.name)
    assert checked == set(classes)
    # each dialfred_msgs type's hash in metadata.yaml is the one rosidl generated at build time
    import yaml
    from ament_index_python.packages import get_package_share_directory
    share = Path(get_package_share_directory('dialfred_msgs'))
    rosidl = {}
    for path in [*share.glob('msg/*.json'), share / 'action' / 'RunTask.json']:
        rosidl.update({h['type_name']: h['hash_string'] for h in json.loads(path.read_text())['type_hashes']})
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    ours = {t['topic_metadata']['type']: t['topic_metadata']['type_description_hash']
            for t in meta['topics_with_message_count']}
    assert meta['storage_identifier'] == 'mcap'
    mine = {k: v for k, v in ours.items() if k.startswith('dialfred_msgs/')}
    assert len(mine) == 6 and all(rosidl[k] == v for k, v in mine.items())


def test_the_same_episode_is_the_same_bytes_and_a_resave_replaces_the_bag(tmp_path):
    a = synthetic_episode()[0].save(tmp_path / 'a')
    b = synthetic_episode()[0].save(tmp_path / 'b')
    for name in ('metadata.yaml', 'valid_unseen_000007.mcap'):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    other = synthetic_episode(seed=1)[0].save(tmp_path / 'a')          # the same task again: replaced
    assert other == a and (a / 'valid_unseen_000007.mcap').read_bytes() != (b / 'valid_unseen_000007.mcap').read_bytes()
    assert sorted(p.name for p in (tmp_path / 'a').iterdir()) == ['valid_unseen_000007']   # no leftovers


def test_png_frames_come_back_exact_and_jpeg_close(tmp_path):
    rec, frames = synthetic_episode('png')
    ep = read_episode(rec.save(tmp_path / 'png'))
    assert ep.counts['/camera/image/compressed'] == 4 and '/camera/image' not in ep.counts
    assert all(np.array_equal(f[2], g) for f, g in zip(ep.frames, frames))
    smooth = np.tile(np.linspace(0, 255, 64, dtype=np.uint8)[None, :, None], (48, 1, 3))
    rec = EpisodeRecorder(**TASK, image_format='jpeg')
    rec.observation(0, smooth, (0, 0, 0, 0), 0.9)
    ep = read_episode(rec.save(tmp_path / 'jpeg'))
    assert np.abs(ep.frames[0][2].astype(int) - smooth).mean() < 3


def test_replay_prints_the_dialogue_and_renders_pictures_from_the_bag_alone(tmp_path, capsys):
    bag = synthetic_episode()[0].save(tmp_path)
    ep = read_episode(bag)
    lines = transcript(ep)
    assert lines[0].startswith('valid_unseen/000007 in FloorPlan301')
    order = [l.strip().split()[0] for l in lines[1:-1]]
    assert order == ['Q', 'Q', '1', '2', 'Q', '3']                      # questions before the action they precede
    assert 'failure (max_steps) after 3 steps, 3 questions' in lines[-1]
    assert replay_main([str(bag), '--gif', str(tmp_path / 'e.gif'), '--sheet', str(tmp_path / 'e.png')]) == 0
    out = capsys.readouterr().out
    assert 'Where is the book' not in out and 'The book is on the desk.' in out and 'Pickup' in out
    from PIL import Image
    with Image.open(tmp_path / 'e.gif') as gif:
        assert gif.n_frames == 1 + 3 + 3                                  # start, 3 QAs, 3 actions
    with Image.open(tmp_path / 'e.png') as sheet:
        assert np.asarray(sheet.convert('L')).std() > 10                  # not blank


def test_a_truncated_or_foreign_bag_is_a_clear_error(tmp_path, capsys):
    bag = synthetic_episode()[0].save(tmp_path / 'ok')
    cut = tmp_path / 'cut' / bag.name
    cut.mkdir(parents=True)
    (cut / 'metadata.yaml').write_bytes((bag / 'metadata.yaml').read_bytes())
    data = (bag / f'{bag.name}.mcap').read_bytes()
    (cut / f'{bag.name}.mcap').write_bytes(data[:len(data) // 2])
    with pytest.raises(BagError, match='cannot be read'):
        read_episode(cut)
    with pytest.raises(BagError, match='no metadata.yaml'):
        read_episode(tmp_path / 'nothing')
    assert replay_main([str(cut)]) == 2 and 'error:' in capsys.readouterr().err
    assert not list((tmp_path / 'cut').glob('*.gif'))


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match='image_format'):
        EpisodeRecorder(**TASK, image_format='bmp')
    rec = EpisodeRecorder(**TASK)
    with pytest.raises(ValueError, match='H x W x 3'):
        rec.observation(0, np.zeros((8, 8), np.uint8), (0, 0, 0, 0), 0.9)
    with pytest.raises(ValueError, match='count from 1'):
        rec.action(0, 'MoveAhead', -1, -1, True, 0)
    with pytest.raises(ValueError, match='unknown result fields'):
        rec.result(sucess=True)
    assert len(rec.messages) == 1                                         # only the task


NEXT = dict(task_id='valid_unseen/000008', scene='FloorPlan301', split='valid_unseen',
            instruction='Pick up the book.', object_nouns=['book'])


def chained_episode(folder: Path) -> tuple[list, list]:
    """Two tasks of a chained episode in one bag, saved after each task (as the recorders do); random frames
    (SYNTHETIC). Returns (the bag's bytes after the first task, the frames of the second task)."""
    rng = np.random.default_rng(5)
    frames = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in range(3)]
    rec = EpisodeRecorder(**TASK, chained=True)
    rec.observation(0, frames[0], (1.0, 2.0, 90.0, 0.0), 0.9)
    rec.question(0, 'location', 'book', 'Where is the book?', 'The book is on the desk.', True)
    rec.action(1, 'Stop', -1, -1, True, 1)
    rec.observation(1, frames[0], (1.0, 2.0, 90.0, 0.0), 0.9)
    rec.result(success=False, steps=1, questions=1, end_reason='stop', last_action='Stop')
    first = sorted(f.read_bytes() for f in rec.save(folder).iterdir())
    with pytest.raises(ValueError, match='already recorded'):
        rec.result(steps=1)
    rec.next_task(**NEXT)
    for k in range(3):
        if k:
            rec.action(k, 'MoveAhead', -1, -1, True, 0)
        rec.observation(k, frames[k], (1.0 + 0.25 * k, 2.0, 90.0, 0.0), 0.9)
    rec.question(2, 'direction', '', 'Which way should I go?', 'Turn left.', True)
    rec.action(3, 'Stop', -1, -1, True, 1)
    rec.observation(3, frames[2], (1.5, 2.0, 90.0, 0.0), 0.9)
    rec.result(success=True, steps=3, questions=1, end_reason='stop', last_action='Stop')
    assert rec.save(folder) == folder / 'valid_unseen_000007_chained'
    return first, frames


def test_a_chained_episode_is_one_bag_that_holds_its_tasks_in_order_each_on_its_own_clock(tmp_path):
    _, frames = chained_episode(tmp_path)
    bag = tmp_path / 'valid_unseen_000007_chained'
    first, second = read_bag(bag)
    assert (first.task['task_id'], second.task['task_id']) == ('valid_unseen/000007', 'valid_unseen/000008')
    assert (first.place, first.of, second.place, second.of) == (1, 2, 2, 2)
    assert first.offset_ns == 0 and second.offset_ns == 2 * STEP_NS        # one step after the first task's result
    assert [f[1] for f in second.frames] == [0, 1, 2, 3] and all(
        np.array_equal(f[2], g) for f, g in zip(second.frames, frames))
    assert [a[:2] for a in second.actions] == [(1, 'MoveAhead'), (2, 'MoveAhead'), (3, 'Stop')]
    assert [q[:2] for q in first.dialogue] == [(0, 'location')] and [q[:2] for q in second.dialogue] == [(2, 'direction')]
    assert (first.result['success'], first.result['steps'], second.result['success'], second.result['steps']) == \
        (False, 1, True, 3)
    rows = independent_read(bag)       # one clock over the whole episode, each result with its own task's dialogue
    assert [t for tp, _, t, _ in rows if tp == '/task'] == [0, 2 * STEP_NS]
    results = [m for tp, _, _, m in rows if tp == '/episode/result']
    assert [[q.question_type for q in r.dialogue] for r in results] == [['location'], ['direction']]
    with pytest.raises(BagError, match='chained episode'):
        read_episode(bag)


def test_a_chained_bag_is_complete_after_each_task_and_replays_task_after_task(tmp_path, capsys):
    first_bytes, _ = chained_episode(tmp_path / 'a')
    chained_episode(tmp_path / 'b')
    bag = tmp_path / 'b' / 'valid_unseen_000007_chained'
    assert sorted(f.read_bytes() for f in bag.iterdir()) == sorted(
        f.read_bytes() for f in (tmp_path / 'a' / bag.name).iterdir())       # the same bytes on a rerun
    assert sorted(f.read_bytes() for f in bag.iterdir()) != first_bytes     # rewritten with the second task
    assert replay_main([str(bag), '--gif', str(tmp_path / 'e.gif'), '--sheet', str(tmp_path / 'e.png')]) == 0
    out = capsys.readouterr().out
    assert 'a chained episode of 2 tasks' in out
    assert out.index('task 1 of 2: valid_unseen/000007') < out.index('task 2 of 2: valid_unseen/000008')
    assert (tmp_path / 'e.gif').stat().st_size > 1000


def test_a_recorder_of_one_task_refuses_a_next_task_and_a_chained_one_before_the_result(tmp_path):
    with pytest.raises(ValueError, match='holds one task'):
        EpisodeRecorder(**TASK).next_task(**NEXT)
    with pytest.raises(ValueError, match='no result yet'):
        EpisodeRecorder(**TASK, chained=True).next_task(**NEXT)

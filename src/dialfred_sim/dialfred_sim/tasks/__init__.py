"""DialFRED tasks: the 25 task types, their goal conditions, the expert, instructions and splits."""

from .schema import TASK_TYPES, Condition, Episode, ExpertAction, Primitive, PublicTask, Task
from .split_files import SPLIT_SIZES, get_task, load_split, split_scenes

__all__ = ['TASK_TYPES', 'Condition', 'Episode', 'ExpertAction', 'Primitive', 'PublicTask', 'Task', 'SPLIT_SIZES', 'get_task',
           'load_split', 'split_scenes']

"""DialFRED tasks: the task types (the paper's 25 and any registered), their goal conditions, the expert, instructions and splits."""

from .schema import Condition, Episode, ExpertAction, Primitive, PublicTask, Task
from .types import TASK_TYPES, TaskType, task_type, task_types
from .split_files import SPLIT_SIZES, get_task, load_split, split_scenes

__all__ = ['TASK_TYPES', 'Condition', 'Episode', 'ExpertAction', 'Primitive', 'PublicTask', 'Task', 'SPLIT_SIZES', 'get_task',
           'load_split', 'split_scenes', 'TaskType', 'task_type', 'task_types']

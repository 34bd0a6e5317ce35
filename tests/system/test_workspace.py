"""The colcon workspace is built and visible through the ament index (what `ros2 run` relies on)."""

from pathlib import Path

from ament_index_python.packages import get_package_prefix, get_package_share_directory
from ament_index_python.resources import get_resources

PACKAGES = ['dialfred_msgs', 'dialfred_sim', 'dialfred_oracle', 'dialfred_questioner',
            'dialfred_performer']


def test_every_package_is_in_the_ament_index():
    for package in PACKAGES:
        assert Path(get_package_share_directory(package), 'package.xml').is_file(), package


def test_dialfred_sim_executables_dir_exists():
    prefix = Path(get_package_prefix('dialfred_sim'))
    assert (prefix / 'lib' / 'dialfred_sim').is_dir()


def test_dialfred_msgs_registers_its_interfaces():
    assert 'dialfred_msgs' in get_resources('rosidl_interfaces')

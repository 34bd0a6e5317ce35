from setuptools import find_packages, setup

package_name = 'dialfred_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(include=[package_name, package_name + '.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['templates/*']},
    install_requires=['setuptools'],
    zip_safe=False,
    license='MIT',
    entry_points={'console_scripts': ['launch = dialfred_bringup.launch:main']},
)

# The Python package mechanism_sim (python/mechanism_sim; doc/python.md), for catkin_python_setup():
# the compiled module _mechanism_sim is built by cmake/python.cmake into the devel space.
from setuptools import setup

from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["mechanism_sim"], package_dir={"": "python"}))

"""Builds the cffi extension asserv._core from the firmware and simulator C sources."""

from setuptools import setup

setup(cffi_modules=["python/asserv/_build_ffi.py:ffibuilder"])

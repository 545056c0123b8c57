"""Builds the cffi extension asserv_sim._core from the firmware and simulator C sources."""

from setuptools import setup

setup(cffi_modules=["_build_ffi.py:ffibuilder"])

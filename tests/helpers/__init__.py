"""Helpers shared by test files (importable as ``helpers`` through pytest's ``pythonpath``):
small models and scene files that several tests build on. Fixtures live in conftest.py."""

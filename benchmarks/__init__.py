"""Benchmarks of rrrobot_gym: run as ``python -m benchmarks.<name> [--quick] [--json FILE]``.

Speed is measured here, never asserted in tests.
"""

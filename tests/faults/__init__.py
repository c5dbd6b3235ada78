"""Fault injection: a private Mission Dispatch stack, random faults from a seed, and checks afterwards.

`python -m tests.faults --seed S` (or `make faults`) runs the long version; `tests/faults/test_fault_suite.py`
runs a short one in `make test`; `tests/faults/test_checks.py` tests the checks on hand-made recordings.
"""

"""What the tests share that is not a fixture: plain functions and classes.

A test module imports from here (or uses a fixture of a conftest.py), never from another test
module or a conftest (tests/test_architecture.py checks it). The fixtures built on these helpers
live in the conftest.py of the tests that use them.
"""

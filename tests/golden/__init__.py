"""Golden outputs of every built-in scenario and solver path, recorded before a re-layout.

``python -m tests.golden.record`` writes ``tests/golden/data/<case>.json`` from the current code;
``tests/unit/test_golden_outputs.py`` holds the code to them. Record only when a change is meant
to move the numbers, and say why in the commit.
"""

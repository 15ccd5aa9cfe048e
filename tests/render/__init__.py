"""Render tests: a package so this directory's conftest does not shadow tests/conftest.py
(both would otherwise be imported as the top-level module ``conftest``)."""

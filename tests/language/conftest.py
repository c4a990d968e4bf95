"""Prints the corpus accuracy in the terminal summary of a run that includes it."""

from __future__ import annotations

CORPUS_SUMMARY: list[str] = []


def pytest_terminal_summary(terminalreporter):
    for line in CORPUS_SUMMARY:
        terminalreporter.write_line(line)

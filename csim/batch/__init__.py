"""Batch runs for CI: a manifest of cases, each with expectations on its run.

``csim batch MANIFEST.yaml`` reads the manifest (:func:`load_manifest`), runs every entry in
parallel processes (:func:`run_batch`), checks each run against its expectations, prints a
pass/fail table and writes a JUnit report. The package, one concern per module:

``expectations``
    one class per expectation kind (``status``, ``max_phi``, ``energy_error``, ``value``,
    ...), registered by name in :data:`EXPECTATIONS`.
``manifest``
    reading and validating the manifest: its keys, its entries' cases and expectations.
``runner``
    running the entries (the worker pool of :mod:`csim.compare.pool`), :class:`Batch` and
    its table.
``junit``
    the JUnit XML report.
"""
from __future__ import annotations

from csim.batch.expectations import EXPECTATIONS, Expectation, Outcome, Range
from csim.batch.junit import write_junit
from csim.batch.manifest import Entry, Manifest, load_manifest
from csim.batch.runner import Batch, CaseRun, run_batch

__all__ = ["EXPECTATIONS", "Batch", "CaseRun", "Entry", "Expectation", "Manifest", "Outcome", "Range", "load_manifest",
           "run_batch", "write_junit"]

"""The JUnit XML report of a batch, for CI systems that show test results.

Layout (the common JUnit schema that Jenkins, GitLab and GitHub's test reporters read)::

    <testsuites name="csim batch" tests="N" failures="F" errors="0" time="T">
      <testsuite name="MANIFEST" tests="N" failures="F" errors="0" skipped="0" time="T" timestamp="...">
        <testcase classname="csim.batch.MANIFEST_STEM" name="ENTRY" time="WALL">
          <failure type="KIND" message="KIND: measured X, expected B">every failed expectation</failure>
          <system-out>the run's summary and every expectation's outcome</system-out>
        </testcase>
      </testsuite>
    </testsuites>

One test case per entry; its ``time`` is the run's wall time [s]. A failed expectation
gives one ``<failure>`` element (a test case may have several).
"""
from __future__ import annotations

import datetime
import io
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

from csim.io.atomic import write_atomically

if TYPE_CHECKING:
    from csim.batch.runner import Batch, CaseRun


def junit_tree(batch: Batch) -> ET.ElementTree:
    """The report as an element tree (see the module's docstring for the layout)."""
    failures = sum(len(run.failures) for run in batch.runs)
    total = f"{sum(run.wall_time for run in batch.runs):.6f}"
    counts = {"tests": str(len(batch.runs)), "failures": str(failures), "errors": "0", "time": total}
    root = ET.Element("testsuites", {"name": "csim batch", **counts})
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    suite = ET.SubElement(root, "testsuite", {"name": str(batch.manifest.path), **counts, "skipped": "0",
                                              "timestamp": stamp})
    for run in batch.runs:
        suite.append(_testcase(run, f"csim.batch.{batch.manifest.path.stem}"))
    ET.indent(root)
    return ET.ElementTree(root)


def _testcase(run: CaseRun, classname: str) -> ET.Element:
    """One entry: a ``<failure>`` per failed expectation, the summary in ``<system-out>``."""
    case = ET.Element("testcase", {"classname": classname, "name": run.entry.name, "time": f"{run.wall_time:.6f}"})
    for outcome in run.failures:
        failure = ET.SubElement(case, "failure", {"type": outcome.kind, "message": outcome.message})
        failure.text = outcome.message
    out = ET.SubElement(case, "system-out")
    lines = [f"case: {run.entry.case_file}" + (f" --set {' --set '.join(run.entry.overrides)}"
                                               if run.entry.overrides else ""),
             run.record.summary(), "expectations:"]
    lines += [f"  {'pass' if o.passed else 'FAIL'}  {o.message}" for o in run.outcomes]
    out.text = "\n".join(lines)
    return case


def write_junit(batch: Batch, path: str | Path) -> None:
    """Write the report to ``path`` atomically (:func:`csim.io.atomic.write_atomically`: mode
    0644 under umask 022, a symbolic link replaced, never written through).

    Raises
    ------
    OSError
        When the folder cannot be created or written.
    """
    buffer = io.BytesIO()
    junit_tree(batch).write(buffer, encoding="utf-8", xml_declaration=True)
    write_atomically(path, buffer.getvalue())

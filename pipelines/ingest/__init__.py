"""Ingest: field logs (CSV, TDMS) and rig recordings (MCAP) into the Parquet lake.

Public API::

    report = ingest_paths(["logs/", "rig/run-12.mcap"], data=DataRoot.resolve(None))
    print(report)          # a short table, one line per file
    report.ok              # False when a file was refused
    report.refusal_lines() # one "<file>: <reason>" per refused file (the CLI's stderr)

Modules: :mod:`.sources` (what and which format), :mod:`.field_csv` (with
:mod:`.csv_header`, :mod:`.csv_chunks`, :mod:`.csv_scan`),
:mod:`.field_tdms`, :mod:`.rig_mcap` (readers), :mod:`.local_time` (timestamps, DST),
:mod:`.field_checks` (channels, SI, impossible values), :mod:`.landing` (partitions,
dedup, atomic Parquet), :mod:`.manifest`, :mod:`.quarantine`, :mod:`.report`,
:mod:`.pipeline` (``ingest_paths``).
"""

from __future__ import annotations

from pipelines.ingest.batch import RefusedFile
from pipelines.ingest.pipeline import ingest_paths
from pipelines.ingest.report import FileResult, FilesRefused, IngestReport

__all__ = ["FileResult", "FilesRefused", "IngestReport", "RefusedFile", "ingest_paths"]

"""Corpus of bad and awkward ingest inputs, built in ``tmp_path`` from code."""

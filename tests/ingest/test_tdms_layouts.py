"""TDMS files laid out as loggers write them: channels in segments of their own, uneven
pieces, garbage sample times (contract 1b)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from pipelines.ingest import ingest_paths
from pipelines.ingest.field_checks import REASON_TIMESTAMP


def _lake(root) -> pl.DataFrame:
    files = sorted(root.table_dir("field_samples").rglob("*.parquet"))
    return pl.concat([pl.read_parquet(f, hive_partitioning=False) for f in files]).sort("time_utc")


@pytest.mark.parametrize("segments", ["groups", "uneven"])
def test_channels_written_in_pieces_land_as_the_one_segment_file(corpus, tmp_path, segments):
    """The same 200 samples written in one segment, or the pressures and the other
    channels in segments of their own, or in uneven pieces whose totals agree: every
    sample lands once with the same values (the builder's sample at 75 MPa quarantined)."""
    roots = {}
    for layout in ("one", segments):
        from warehouse.store import DataRoot

        roots[layout] = DataRoot(tmp_path / layout)
        path = corpus.tdms_file(tmp_path / f"{layout}.tdms", n=200, segments=layout)
        result = ingest_paths([path], data=roots[layout]).files[0]
        assert result.status == "landed", result.message
        assert (result.rows_read, result.rows_landed, result.rows_quarantined) == (200, 199, 1)
    columns = [c for c in _lake(roots["one"]).columns if c != "source_sha256"]
    assert _lake(roots[segments]).select(columns).equals(_lake(roots["one"]).select(columns))


def test_a_garbage_sample_time_is_quarantined_and_the_command_goes_on(corpus, tmp_path, root):
    """A timestamp channel with one NaT (npTDMS reads it back as year 294181) and one
    time past year 9999: those two samples are quarantined as unreadable times, the rest
    land, and a CSV given with it lands too."""
    n = 50
    t0 = np.datetime64("2026-03-02T06:00:00", "us")
    stamps = t0 + (np.arange(n) * 10_000).astype("timedelta64[us]")
    stamps[3] = np.datetime64("NaT")
    stamps[8] = np.datetime64("10000-01-01T00:00:00", "us")
    tdms = corpus.tdms_file(tmp_path / "stamps.tdms", n=n, stamps=stamps)
    csv = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(10))
    report = ingest_paths([tdms, csv], data=root)
    first, second = report.files
    assert first.status == "landed", first.message
    assert first.quarantined_by_reason[REASON_TIMESTAMP] == 2
    assert first.rows_landed == n - 3  # and the builder's sample at 75 MPa
    assert (second.status, second.rows_landed) == ("landed", 10)


def test_a_panic_in_a_reader_refuses_that_file_and_the_command_goes_on(
    corpus, tmp_path, root, monkeypatch
):
    """A panic in polars' Rust (a BaseException, not an Exception) while one file is
    read: that file is refused as unreadable, naming the panic, and the next file
    lands (the panic ended the whole command, no manifest row written). Injected: no
    known input panics any more."""
    from polars.exceptions import PanicException

    from pipelines.ingest import field_tdms

    def panics(*args, **kwargs):
        raise PanicException("DateTime + TimeDelta overflowed")

    monkeypatch.setattr(field_tdms, "_si_frame", panics)
    tdms = corpus.tdms_file(tmp_path / "log.tdms", n=20)
    csv = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(10))
    first, second = ingest_paths([tdms, csv], data=root).files
    assert first.status == "refused"
    assert "unreadable (PanicException: DateTime + TimeDelta overflowed)" in first.message
    assert (second.status, second.rows_landed) == ("landed", 10)


def test_an_infinite_tdms_value_is_quarantined_as_a_csv_one_is(corpus, tmp_path, root):
    """A TDMS float can hold an infinity (a CSV's is quarantined as unparsable): an
    infinite x, speed or depth is beyond any limit, also without a hoist description
    (its unknown stroke, winder and shaft read as unbounded); a large finite x lands."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    n = 6
    wave = {"wf_start_time": np.datetime64("2026-03-02T06:00:00", "us"), "wf_increment": 0.01}
    x, speed, depth = np.zeros(n), np.zeros(n), np.zeros(n)
    x[1], x[2], x[5] = np.inf, -np.inf, 1e5  # 100 m: no stroke known, landed
    speed[3], depth[4] = np.inf, np.inf
    values = {**{f"p{i}": (np.full(n, 4.8), "MPa") for i in range(1, 5)},
              "x1": (x, "mm"), "speed": (speed, "m/s"), "depth": (depth, "m")}  # fmt: skip
    path = tmp_path / "inf.tdms"
    with TdmsWriter(path) as writer:
        writer.write_segment([
            RootObject({"site": "xuzhou-north", "hoist": "tdms-hoist", "timezone": "UTC"}),
            GroupObject("hoist"),
            *(ChannelObject("hoist", name, data, properties={"unit_string": unit, **wave})
              for name, (data, unit) in values.items()),
        ])  # fmt: skip
    result = ingest_paths([path], data=root).files[0]
    assert (result.status, result.rows_landed, result.rows_quarantined) == ("landed", 2, 4)
    assert result.quarantined_by_reason == {
        "piston beyond a stroke from mid-stroke (x1)": 2,
        "speed above twice the winder's maximum": 1,
        "depth outside the shaft": 1,
    }
    assert np.isfinite(_lake(root).select("x1_m", "speed_m_s", "depth_m").to_numpy()).all()


def _named_tdms(path, rename) -> None:
    """A contract-1b TDMS of 50 samples whose channels are named ``rename(name)``; its
    timestamp channel jitters off the waveform's time base (2 ms every other sample)."""
    from nptdms import ChannelObject, RootObject, TdmsWriter

    n = 50
    t0 = np.datetime64("2026-03-02T06:00:00", "us")
    stamps = t0 + (np.arange(n) * 10_000 + (np.arange(n) % 2) * 2_000).astype("timedelta64[us]")
    wave = {"wf_start_time": t0, "wf_increment": 0.01, "wf_start_offset": 0.0}
    values = {
        **{f"p{i}": (np.full(n, 4.8 + 0.001 * i), "MPa") for i in range(1, 5)},
        "depth": (np.linspace(0, 60, n), "m"),
        "speed": (np.full(n, 1.0), "m/s"),
    }
    channels = [
        ChannelObject("hoist", rename(name), data, properties={"unit_string": unit, **wave})
        for name, (data, unit) in values.items()
    ]
    channels.append(ChannelObject("hoist", rename("timestamp"), stamps))
    root = RootObject({"site": "xuzhou-north", "hoist": "tdms-hoist", "timezone": "UTC"})
    with TdmsWriter(path) as writer:
        writer.write_segment([root, *channels])


def test_tdms_channel_names_whatever_their_case_land_as_the_csvs_do(tmp_path):
    """A LabVIEW user names the channels ``P1`` or ``Depth``, as a CSV's columns may be
    (contract 1b: channels named as the CSV columns, same meaning): the file lands as the
    lower-case one, its timestamp channel giving the sample times."""
    from warehouse.store import DataRoot

    lakes = {}
    for label, rename in (("lower", str), ("upper", str.upper), ("title", str.capitalize)):
        root = DataRoot(tmp_path / label)
        _named_tdms(tmp_path / f"{label}.tdms", rename)
        result = ingest_paths([tmp_path / f"{label}.tdms"], data=root).files[0]
        assert result.status == "landed", result.message
        assert (result.rows_read, result.rows_landed) == (50, 50)
        assert "unknown channel" not in result.message
        lakes[label] = _lake(root).drop("source_sha256")
    assert lakes["lower"]["time_utc"].dt.microsecond()[1] == 12_000  # the jittered stamp
    assert lakes["upper"].equals(lakes["lower"])
    assert lakes["title"].equals(lakes["lower"])


def test_two_tdms_channels_one_name_but_for_case_refuse_the_file(tmp_path, root):
    _named_tdms(tmp_path / "a.tdms", str)
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(tmp_path / "a.tdms", mode="a") as writer:
        writer.write_segment([ChannelObject("hoist", "P1", np.full(50, 9.0))])
    result = ingest_paths([tmp_path / "a.tdms"], data=root).files[0]
    assert result.status == "refused"
    assert "hoist/P1" in result.message
    assert "p1" in result.message

"""Re-ingest, renamed copies, overlapping files, growing files; rig recordings (MCAP)."""

from __future__ import annotations

import datetime as dt
import hashlib
import shutil
from zoneinfo import ZoneInfo

import polars as pl

from pipelines.ingest import ingest_paths
from warehouse.store import DataRoot, open_reader


def _lake_checksum(root: DataRoot) -> tuple[int, str]:
    files = sorted(root.lake.glob("*/site=*/hoist=*/date=*/*.parquet"))
    frame = pl.concat([pl.read_parquet(f, hive_partitioning=False) for f in files], how="diagonal")
    digest = hashlib.sha256(frame.sort("time_utc").write_ipc(None).getvalue()).hexdigest()
    return frame.height, digest


def _counts(root: DataRoot) -> tuple[int, int]:
    with open_reader(root) as con:
        manifest = con.sql("SELECT count(*) FROM manifest").fetchall()[0][0]
        quarantine = con.sql("SELECT count(*) FROM quarantine").fetchall()[0][0]
    return manifest, quarantine


def test_reingest_is_a_no_op(corpus, tmp_path, root):
    rows = corpus.data_rows(40)
    rows[3][1] = "oops"
    path = corpus.csv_file(tmp_path / "day.csv", rows)
    first = ingest_paths([path, corpus.tdms_file(tmp_path / "log.tdms")], data=root)
    before = (_lake_checksum(root), _counts(root))
    again = ingest_paths([path, tmp_path / "log.tdms"], data=root)
    assert [f.status for f in again] == ["skipped", "skipped"]
    assert all(f.rows_read == 0 for f in again)
    assert (_lake_checksum(root), _counts(root)) == before
    assert first.files[0].rows_landed == 39


def test_same_content_under_a_new_name_is_skipped(corpus, tmp_path, root):
    path = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(20))
    ingest_paths([path], data=root)
    copy = tmp_path / "export-again.csv"
    shutil.copy(path, copy)
    report = ingest_paths([copy], data=root)
    assert report.files[0].status == "skipped"
    assert str(path) in report.files[0].message
    assert _lake_checksum(root)[0] == 20


def test_overlapping_files_land_each_sample_once(corpus, tmp_path, root):
    rows = corpus.data_rows(30)
    first = corpus.csv_file(tmp_path / "a.csv", rows[:20])
    second = corpus.csv_file(tmp_path / "b.csv", rows[10:])
    report = ingest_paths([first, second], data=root)
    b = report.files[1]
    assert (b.rows_read, b.rows_landed, b.rows_duplicate, b.rows_quarantined) == (20, 10, 10, 0)
    lake = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    assert lake.height == 30
    assert lake["time_utc"].n_unique() == 30


def test_overlap_with_other_values_is_quarantined_as_conflict(corpus, tmp_path, root):
    rows = corpus.data_rows(10)
    ingest_paths([corpus.csv_file(tmp_path / "a.csv", rows)], data=root)
    changed = [list(r) for r in rows[5:]]
    changed[0][1] = "9.999"
    report = ingest_paths([corpus.csv_file(tmp_path / "b.csv", changed)], data=root)
    b = report.files[0]
    assert (b.rows_read, b.rows_landed, b.rows_duplicate, b.rows_quarantined) == (5, 0, 4, 1)
    assert b.quarantined_by_reason == {"conflicts with landed sample": 1}
    with open_reader(root) as con:
        raw = con.sql("SELECT raw FROM quarantine").fetchall()[0][0]
    assert "9.999" in raw


def test_growing_file_is_picked_up_where_it_stopped(corpus, tmp_path, root):
    rows = corpus.data_rows(30)
    full = corpus.csv_file(tmp_path / "full.csv", rows).read_bytes()
    live = tmp_path / "live.csv"
    cut = full.index(b"2026-03-02 06:00:00.120")
    live.write_bytes(full[: cut + 10])  # 12 complete rows, the 13th cut
    first = ingest_paths([live], data=root).files[0]
    assert first.status == "partial"
    assert (first.rows_read, first.rows_landed) == (12, 12)
    assert first.bytes_consumed == cut
    live.write_bytes(full)  # it grew and is complete now
    second = ingest_paths([live], data=root).files[0]
    assert second.status == "landed"
    assert "resumed at byte" in second.message
    assert (second.rows_read, second.rows_landed, second.rows_duplicate) == (18, 18, 0)
    assert second.bytes_consumed == len(full)
    assert _lake_checksum(root)[0] == 30
    lake = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    assert sorted(lake["source_line"].to_list()) == list(range(7, 37))
    # small appends merge into the partition's newest part: one part, not one per pickup
    assert len(list(root.table_dir("field_samples").rglob("*.parquet"))) == 1


def test_a_landed_file_that_grows_is_resumed_not_read_again(corpus, tmp_path, root):
    """A logger that flushes whole lines: the file lands whole, then grows under the
    same name; the second ingest reads only the new rows, and the first version's bad
    rows stay quarantined once."""
    rows = corpus.data_rows(40)
    rows[5][1], rows[6][1] = "abc", "-1"
    live = tmp_path / "live.csv"
    live.write_bytes(corpus.csv_file(tmp_path / "first.csv", rows[:20]).read_bytes())
    first = ingest_paths([live], data=root).files[0]
    assert (first.status, first.rows_landed, first.rows_quarantined) == ("landed", 18, 2)
    live.write_bytes(corpus.csv_file(tmp_path / "full.csv", rows).read_bytes())
    second = ingest_paths([live], data=root).files[0]
    assert second.status == "landed"
    assert "resumed at byte" in second.message
    assert (second.rows_read, second.rows_landed, second.rows_duplicate) == (20, 20, 0)
    assert second.rows_quarantined == 0
    assert _lake_checksum(root)[0] == 38
    assert _counts(root) == (2, 2)  # two manifest rows, the two bad lines once each


def test_a_file_growing_through_the_repeated_hour_lands_each_pass_once(corpus, tmp_path, root):
    """A New York logger at 1 Hz across the end of daylight-saving time (local times
    01:00-01:59 twice), picked up cut in the second pass, again later in it, then whole:
    every sample lands once at its true instant, as the whole file read at once does
    (each resumed read starts where the earlier version left the repeated hour; the
    file's 8 hours are more than the 4 a resume reads back, so the tail is sized from
    the bytes of an hour, not the whole prefix)."""
    zone = ZoneInfo("America/New_York")
    instants = [
        dt.datetime(2026, 10, 31, 22, 50, tzinfo=dt.UTC) + dt.timedelta(seconds=k)
        for k in range(8 * 3600 + 1)  # 18:50 EDT .. 01:50 EST
    ]
    rows = corpus.data_rows(len(instants))
    for row, t in zip(rows, instants, strict=True):
        row[0] = t.astimezone(zone).strftime("%Y-%m-%d %H:%M:%S.000")
    header = {**corpus.HEADER, "timezone": "America/New_York"}
    full = corpus.csv_file(tmp_path / "full.csv", rows, header=header).read_bytes()
    live = tmp_path / "live.csv"
    for cut_at in (dt.datetime(2026, 11, 1, 6, 20), dt.datetime(2026, 11, 1, 6, 40)):
        k = instants.index(cut_at.replace(tzinfo=dt.UTC))  # 01:20 and 01:40 EST
        at = full.index(rows[k][0].encode(), full.index(b"01:59:59.000"))  # second pass
        live.write_bytes(full[: at + 12])  # the line at cut_at cut off
        assert ingest_paths([live], data=root).files[0].status == "partial"
    live.write_bytes(full)
    last = ingest_paths([live], data=root).files[0]
    assert last.status == "landed"
    lake = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    assert lake.height == len(instants)
    assert lake["time_utc"].sort().to_list() == instants
    assert _counts(root)[1] == 0  # nothing quarantined as a conflict


def test_truncated_tdms_then_the_complete_file_lands_every_sample_once(corpus, tmp_path, root):
    full = corpus.tdms_file(tmp_path / "full.tdms", n=400)
    cut = tmp_path / "cut.tdms"
    cut.write_bytes(full.read_bytes()[: -250 * 8])  # speed has 150 of 400 values
    first = ingest_paths([cut], data=root).files[0]
    assert (first.status, first.rows_read, first.rows_landed) == ("partial", 150, 149)
    second = ingest_paths([full], data=root).files[0]
    assert second.status == "landed"
    assert (second.rows_landed, second.rows_duplicate, second.rows_quarantined) == (250, 149, 1)
    assert second.quarantined_by_reason == {"pressure above 60 MPa (p1)": 1}  # not conflicts
    lake = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    assert lake.height == 399
    assert lake["speed_m_s"].null_count() == 0


def test_large_file_streams_in_batches_and_lands_every_row(corpus, tmp_path, root):
    rows = corpus.data_rows(3000)
    rows[1500][1] = "bad"
    path = corpus.csv_file(tmp_path / "big.csv", rows)
    report = ingest_paths([path], data=root, batch_bytes=16 * 1024)
    result = report.files[0]
    assert (result.rows_read, result.rows_landed, result.rows_quarantined) == (3000, 2999, 1)
    lake = pl.read_parquet(sorted(root.table_dir("field_samples").rglob("*.parquet")))
    assert lake.height == 2999
    assert lake["time_utc"].n_unique() == 2999


def test_day_boundary_splits_partitions(corpus, tmp_path, root):
    import datetime as dt

    rows = corpus.data_rows(20, start=dt.datetime(2026, 3, 2, 23, 59, 59, 900000))
    ingest_paths([corpus.csv_file(tmp_path / "midnight.csv", rows)], data=root)
    dates = sorted(p.name for p in root.table_dir("field_samples").glob("site=*/hoist=*/date=*"))
    assert dates == ["date=2026-03-02", "date=2026-03-03"]


def test_report_prints_a_table(corpus, tmp_path, root):
    report = ingest_paths(
        [corpus.csv_file(tmp_path / "a.csv", corpus.data_rows(3)), tmp_path / "missing.csv"],
        data=root,
    )
    text = str(report)
    assert "a.csv" in text
    assert "refused" in text
    assert "no such file" in text
    assert not report.ok


# ------------------------------------------------------------------------------ MCAP
def test_rig_recording_is_aligned_on_the_pressure_timeline(corpus, tmp_path, root):
    report = ingest_paths([corpus.mcap_file(tmp_path / "rig.mcap")], data=root)
    result = report.files[0]
    assert (result.status, result.rows_read, result.rows_landed) == ("landed", 2000, 2000)
    assert (result.site, result.hoist) == ("rig", "rig-a")
    files = sorted(root.table_dir("rig_samples").glob("site=rig/hoist=rig-a/date=*/*.parquet"))
    frame = pl.read_parquet(files, hive_partitioning=False).sort("time_utc")
    assert frame["step"].to_list()[::500] == [0, 1, 2, 3]
    assert frame["pressure_setpoint_pa"][600] == 3e6
    assert frame["velocity_setpoint_m_s"][0] == 5e-3
    # pressure at t+0.1 ms sees displacement logged at t (even i) or t-1 ms (odd i)
    assert frame["x_m"][10] == 0.005 * 10 * 1e-3
    assert frame["x_m"][11] == 0.005 * 10 * 1e-3
    assert frame["oil_temp_c"][1500] == 36.0
    assert frame["p_rod_pa"][0] == 0.5e6


def test_truncated_recording_lands_what_is_complete(corpus, tmp_path, root):
    path = corpus.mcap_file(tmp_path / "cut.mcap", truncate_fraction=0.6)
    result = ingest_paths([path], data=root).files[0]
    assert result.status == "partial"
    assert "truncated" in result.message
    assert 0 < result.rows_landed < 2000
    assert result.balanced


def test_unknown_topic_is_ignored_and_named(corpus, tmp_path, root):
    result = ingest_paths([corpus.mcap_file(tmp_path / "cam.mcap", unknown_topic=True)], data=root)
    (file,) = result.files
    assert file.status == "landed"
    assert "/rig/camera" in file.message
    assert file.rows_landed == 2000


def test_a_rig_geometry_calibrate_refuses_is_said_by_ingest(corpus, tmp_path, root):
    """The samples of a recording whose ``/rig/info`` gives a rod wider than the bore
    land (they are measurements), and ingest says what ``ropeload calibrate`` will
    refuse; a ``/rig/info`` without its bore refuses the file, naming the field."""
    path = corpus.mcap_file(tmp_path / "rod.mcap", info={"rod_mm": 200})
    (file,) = ingest_paths([path], data=root).files
    assert (file.status, file.rows_landed) == ("landed", 2000)
    assert "topic /rig/info: rod_mm 200.0: not at least 0 and below bore_mm 100.0" in file.message
    assert "calibrate will refuse" in file.message
    path = corpus.mcap_file(tmp_path / "nobore.mcap", info={"bore_mm": None})
    (file,) = ingest_paths([path], data=root).files
    assert file.status == "refused"
    assert "topic /rig/info: no valid message, so no rig_id" in file.message
    assert "missing or invalid bore_mm" in file.message


def test_non_jsonschema_topic_refuses_the_file(corpus, tmp_path, root):
    path = corpus.mcap_file(tmp_path / "proto.mcap", bad_encoding_topic="/rig/displacement")
    (file,) = ingest_paths([path], data=root).files
    assert file.status == "refused"
    assert "topic /rig/displacement" in file.message
    assert "jsonschema" in file.message
    assert not root.table_dir("rig_samples").exists()


def test_a_pressure_message_of_nan_is_quarantined_as_not_a_number(corpus, tmp_path, root):
    path = corpus.mcap_file(tmp_path / "nan.mcap", nan_messages=2)
    (file,) = ingest_paths([path], data=root).files
    assert (file.rows_landed, file.rows_quarantined) == (1998, 2)
    assert file.quarantined_by_reason == {"not a number (p_rodless)": 2}
    with open_reader(root) as con:
        raw = con.sql("SELECT raw FROM quarantine ORDER BY raw").fetchall()
    # where each is in the recording: the builder's first two pressure messages
    assert [r[0][:48] for r in raw] == [
        "message 0, log time 2026-03-02T14:00:00.000100+0",
        "message 1, log time 2026-03-02T14:00:00.001100+0",
    ]


def test_a_displacement_of_nan_is_quarantined_not_landed(corpus, tmp_path, root):
    """A non-finite value of another topic is a bad message of that topic, as a pressure
    of NaN is: quarantined with its topic (not a row), not landed as x_m = NaN, which
    made the Savitzky-Golay derivatives of its whole block NaN and left calibrate with
    "0 steady steps" and no word why."""
    path = corpus.mcap_file(tmp_path / "nanx.mcap", nan_displacements=2)
    (file,) = ingest_paths([path], data=root).files
    assert (file.rows_read, file.rows_landed, file.rows_quarantined) == (2000, 2000, 0)
    assert "2 invalid message(s) of other topics quarantined" in file.message
    with open_reader(root) as con:
        rows = con.sql("SELECT topic, reason FROM quarantine").fetchall()
    assert rows == [("/rig/displacement", "message does not match the /rig/displacement "
                     "schema: missing or invalid x_mm")] * 2  # fmt: skip
    files = sorted(root.table_dir("rig_samples").glob("site=rig/hoist=rig-a/date=*/*.parquet"))
    x = pl.read_parquet(files, hive_partitioning=False).sort("time_utc")["x_m"]
    assert x.is_nan().sum() == 0
    assert x.null_count() == 4  # before the first valid displacement (logged at 4 ms)
    assert x[4] == 0.005 * 4 * 1e-3


def test_invalid_pressure_messages_are_quarantined_with_topic(corpus, tmp_path, root):
    path = corpus.mcap_file(tmp_path / "bad.mcap", bad_messages=3)
    (file,) = ingest_paths([path], data=root).files
    assert (file.rows_read, file.rows_landed, file.rows_quarantined) == (2000, 1997, 3)
    with open_reader(root) as con:
        topics = con.sql("SELECT DISTINCT topic, line FROM quarantine").fetchall()
    assert topics == [("/rig/pressure", None)]


def test_invalid_messages_of_other_topics_keep_the_rows_balanced(corpus, tmp_path, root):
    """Bad messages of the other topics are quarantined but are not rows (contract 3 counts
    /rig/pressure messages): they were counted as read and not as quarantined, so read
    was 2003 for 2000 landed, 0 quarantined, 0 duplicates."""
    path = corpus.mcap_file(tmp_path / "badx.mcap", bad_displacements=3)
    (file,) = ingest_paths([path], data=root).files
    counts = (file.rows_read, file.rows_landed, file.rows_quarantined, file.rows_duplicate)
    assert counts == (2000, 2000, 0, 0)
    assert file.balanced
    assert "3 invalid message(s) of other topics quarantined (not rows)" in file.message
    with open_reader(root) as con:
        manifest = con.sql("SELECT rows_read, rows_landed FROM manifest").fetchall()
        topics = con.sql("SELECT topic, count(*) FROM quarantine GROUP BY topic").fetchall()
    assert manifest == [(2000, 2000)]
    assert topics == [("/rig/displacement", 3)]


def test_a_re_export_under_a_new_name_is_known_after_its_first_skip(corpus, tmp_path, root):
    """The same content under a new name is skipped (nothing landed twice) and its path
    recorded: the nightly's new-file test knows it from then on (it read and hashed it
    again every night, counting it new)."""
    from pipelines.hoists import is_new, known_files

    path = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(20))
    ingest_paths([path], data=root)
    copy = tmp_path / "export-again.csv"
    shutil.copy(path, copy)
    assert is_new(copy, known_files(root))
    assert ingest_paths([copy], data=root).files[0].status == "skipped"
    assert not is_new(copy, known_files(root))
    assert _counts(root) == (1, 0)  # still one manifest row
    assert ingest_paths([copy], data=root).files[0].status == "skipped"  # and again: alike


def test_a_lookup_failing_on_a_new_files_first_batch_refuses_that_file_alone(
    corpus, tmp_path, root
):
    """A new CSV's header and first batch are read while the file is hashed: an error
    there (here the caller's hoist lookup failing for its hoist) refuses that file,
    naming it, as it would when read after the hash; the command goes on and the next
    file lands."""

    def lookup(site: str, hoist: str):
        if site == "xuzhou-north":
            raise ValueError("the hoist register is unavailable")
        return None

    bad = corpus.csv_file(tmp_path / "day.csv", corpus.data_rows(20))
    text = bad.read_text(encoding="utf-8")
    assert "xuzhou-north" in text
    good = tmp_path / "other.csv"
    good.write_text(text.replace("xuzhou-north", "other-mine"), encoding="utf-8")
    report = ingest_paths([bad, good], data=root, hoist_lookup=lookup)
    assert [f.status for f in report.files] == ["refused", "landed"]
    assert str(bad) in report.files[0].message
    assert "the hoist register is unavailable" in report.files[0].message
    assert report.files[1].rows_landed == 20


def test_capitalised_channel_names_land_as_the_contracts(corpus, tmp_path, root):
    """A column line written ``Timestamp,P1,...,Depth,Speed,Oil_Temp`` (an export's
    capitalisation) lands every channel as the contract's lower-case names do: the same
    samples, none ignored."""
    rows = corpus.data_rows(30)
    lower = corpus.csv_file(tmp_path / "lower.csv", rows)
    upper = corpus.csv_file(
        tmp_path / "upper.csv", rows, columns=[c.title() for c in corpus.COLUMNS]
    )
    other = DataRoot.resolve(tmp_path / "other")
    first = ingest_paths([lower], data=root).files[0]
    second = ingest_paths([upper], data=other).files[0]
    assert (first.rows_landed, second.rows_landed) == (30, 30)
    assert "ignored" not in second.message

    def landed(data: DataRoot) -> pl.DataFrame:
        files = sorted(data.table_dir("field_samples").rglob("*.parquet"))
        frame = pl.read_parquet(files, hive_partitioning=False).sort("time_utc")
        return frame.drop("source_sha256")

    assert landed(root).equals(landed(other))


def test_a_file_whose_ingest_was_killed_before_its_manifest_row_counts_its_rows_as_landed(
    corpus, tmp_path, root
):
    """An ingest killed after its Parquet parts and before its manifest row (a probe:
    SIGTERM ~2 s into a 124 MB file) left the file's rows in the lake, and the re-run
    called them all duplicates: the manifest said the file put nothing in the lake. The
    state is made here as the kill leaves it: the lake's parts written, the warehouse
    (published only when an ingest ends, ``open_writer``) without the file's manifest
    and quarantine rows. Ingested again, the file's own rows are landed by it and
    nothing lands twice."""
    from warehouse.store import open_writer

    rows = corpus.data_rows(40)
    rows[3][1] = "oops"
    path = corpus.csv_file(tmp_path / "day.csv", rows)
    first = ingest_paths([path], data=root).files[0]
    lake = _lake_checksum(root)
    with open_writer(root) as con:
        for table in ("manifest", "quarantine"):
            con.execute(f"DELETE FROM {table} WHERE source_sha256 = ?", [first.sha256])
    again = ingest_paths([path], data=root).files[0]
    counts = (again.rows_read, again.rows_landed, again.rows_duplicate, again.rows_quarantined)
    assert (again.status, counts) == ("landed", (40, 39, 0, 1))
    assert _lake_checksum(root) == lake
    with open_reader(root) as con:
        (quarantined,) = con.execute(
            "SELECT count(*) FROM quarantine WHERE source_sha256 = ?", [first.sha256]
        ).fetchone()
        (manifest,) = con.execute("SELECT rows_landed FROM manifest").fetchone()
    assert (quarantined, manifest) == (1, 39)


def test_a_finished_export_without_a_last_line_end_lands_its_last_row_when_said_complete(
    corpus, tmp_path, root
):
    """A last line without a line end may be a row still being written: held back, the
    file ``partial``, until it grows. A finished export that simply ends without one
    would never land that row; ``complete`` says the file is finished: the row lands,
    whether the file is new or was left partial before (then read on from where it
    stopped, the manifest's one row counting the whole file)."""
    path = corpus.csv_file(tmp_path / "export.csv", corpus.data_rows(10))
    path.write_bytes(path.read_bytes().rstrip(b"\r\n"))
    held = ingest_paths([path], data=root).files[0]
    assert (held.status, held.rows_read, held.rows_landed) == ("partial", 9, 9)
    assert "held back until the file grows" in held.message
    assert "--complete" in held.message
    finished = ingest_paths([path], data=root, complete=True).files[0]
    assert (finished.status, finished.rows_read, finished.rows_landed) == ("landed", 1, 1)
    assert _lake_checksum(root)[0] == 10
    with open_reader(root) as con:
        rows = con.execute(
            "SELECT status, rows_read, rows_landed, bytes_consumed, size_bytes FROM manifest"
        ).fetchall()
    assert rows == [("landed", 10, 10, path.stat().st_size, path.stat().st_size)]
    again = ingest_paths([path], data=root, complete=True).files[0]
    assert again.status == "skipped"
    fresh = DataRoot.resolve(tmp_path / "fresh")
    new = ingest_paths([path], data=fresh, complete=True).files[0]
    assert (new.status, new.rows_read, new.rows_landed) == ("landed", 10, 10)
    assert _lake_checksum(fresh) == _lake_checksum(root)


def test_a_row_a_file_repeats_is_its_duplicate_across_batches(corpus, tmp_path, root):
    """Every row written twice, read in small batches: a repeat landed by an earlier
    batch of the same file is a duplicate, not a row the file landed again (the killed
    attempt's rows are the same file's at the same line, a repeat is at another)."""
    rows = corpus.data_rows(100)
    path = corpus.csv_file(tmp_path / "twice.csv", [r for row in rows for r in (row, row)])
    (file,) = ingest_paths([path], data=root, batch_bytes=1024).files
    counts = (file.rows_read, file.rows_landed, file.rows_duplicate, file.rows_quarantined)
    assert counts == (200, 100, 100, 0)
    assert _lake_checksum(root)[0] == 100


def test_a_complete_file_that_grows_after_all_skips_the_rest_of_its_last_row(
    corpus, tmp_path, root
):
    """Said complete, a file's last line without a line end landed as a row; if the
    logger then writes the rest of that line and more rows, the rest is not read as a
    row of its own (it would be a fragment, quarantined), the rows after it land."""
    rows = corpus.data_rows(12)
    path = corpus.csv_file(tmp_path / "log.csv", rows)
    text = path.read_bytes()
    cut = text.rindex(b"\n", 0, len(text) - 1)  # the start of the last line
    last = text[cut + 1 :]  # the last line, its line end included
    cut_at = cut + 1 + len(last) // 2
    path.write_bytes(text[:cut_at])
    first = ingest_paths([path], data=root, complete=True).files[0]
    assert (first.status, first.rows_read, first.rows_quarantined) == ("landed", 12, 1)
    more = corpus.csv_file(tmp_path / "more.csv", corpus.data_rows(15)[12:])
    added = more.read_bytes().split(b"\n", maxsplit=0)[0]
    header_end = added.index(b"\ntimestamp")
    body = added[added.index(b"\n", header_end + 1) + 1 :]
    path.write_bytes(text[:cut_at] + text[cut_at:] + body)
    grown = ingest_paths([path], data=root).files[0]
    assert (grown.rows_read, grown.rows_landed, grown.rows_quarantined) == (3, 3, 0)
    assert "which an ingest --complete read as the file's last row" in grown.message

"""``ropeload query``: read-only SQL on the published warehouse, read-only in fact.

Two independent fences, each enough against the escapes a keyword filter misses
(``COPY ... TO``, ``ATTACH``, ``EXPORT DATABASE``, ``select 1; copy ...``, ``SET``,
``PRAGMA``, ``read_csv('/etc/passwd')``):

1. :func:`check_read_only`: DuckDB's own parser (``duckdb.extract_statements``) must
   find exactly one statement, of type ``SELECT`` (which covers ``WITH ... SELECT``,
   ``FROM t``, ``VALUES``, ``DESCRIBE``, ``SHOW``, ``SUMMARIZE``) or ``EXPLAIN`` of one
   such statement. Anything else is refused before a connection is opened.
2. The statement runs on :func:`warehouse.store.open_reader` with ``sandbox=True``: the
   warehouse attached read-only, no file outside ``<data>/lake`` reachable, extensions
   off, configuration locked. A file function pointed outside the lake fails there and
   is reported as a refusal too.
"""

from __future__ import annotations

import io
import json
from typing import Literal

import duckdb
import polars as pl

from warehouse.store import DataRoot, open_reader

__all__ = ["OutputFormat", "QueryRefused", "check_read_only", "format_result", "run_query"]

OutputFormat = Literal["table", "csv", "json"]

_WHAT_IS_ALLOWED = "read-only audit interface: one SELECT, WITH ... SELECT or EXPLAIN SELECT"


class QueryRefused(Exception):
    """SQL that ``ropeload query`` will not run; the message is one line, ``refused: ...``."""


def _tokens(sql: str) -> list[tuple[int, str]]:
    """(offset, text) of the tokens of ``sql``, comments left out (DuckDB's tokenizer)."""
    spans = duckdb.tokenize(sql)
    tokens = []
    for k, (start, kind) in enumerate(spans):
        end = spans[k + 1][0] if k + 1 < len(spans) else len(sql)
        if kind != duckdb.token_type.comment:
            tokens.append((start, sql[start:end].strip()))
    return tokens


def _explained(sql: str) -> str:
    """The statement under ``EXPLAIN [ANALYZE] [(options)]`` (``sql`` starts with EXPLAIN)."""
    tokens = _tokens(sql)[1:]
    if tokens and tokens[0][1].upper() in ("ANALYZE", "ANALYSE"):
        tokens = tokens[1:]
    if tokens and tokens[0][1].startswith("("):
        depth = 0
        while tokens:
            _, text = tokens.pop(0)
            if not text.startswith("'"):  # operators carry the brackets; strings do not count
                depth += text.count("(") - text.count(")")
            if depth <= 0:
                break
    return sql[tokens[0][0] :] if tokens else ""


def _kind(statement: duckdb.Statement) -> str:
    """DuckDB's statement type: ``SELECT``, ``COPY``, ``MERGE INTO``; ``?`` if unnamed."""
    try:
        return statement.type.name.replace("_", " ")
    except ValueError:  # a type the Python API has no name for (``UPDATE EXTENSIONS``)
        return "?"


def _label(statement: duckdb.Statement) -> str:
    """What the statement is, for the refusal: ``COPY``, ``CHECKPOINT (CALL)``, ``INSERT``."""
    kind = _kind(statement)
    tokens = _tokens(statement.query)
    keyword = tokens[0][1].upper() if tokens else kind
    if keyword == kind.split()[0] or not keyword.isalpha() or keyword == "WITH":
        return kind
    return f"{keyword} ({kind})" if kind != "?" else keyword


def check_read_only(sql: str) -> duckdb.Statement:
    """The one read-only statement of ``sql``, parsed by DuckDB; :class:`QueryRefused` else.

    Parse errors propagate as DuckDB's own ``duckdb.ParserException``.
    """
    statements = duckdb.extract_statements(sql)
    if not statements:
        raise QueryRefused(f"refused: no SQL statement given ({_WHAT_IS_ALLOWED})")
    if len(statements) > 1:
        kinds = ", ".join(_label(statement) for statement in statements)
        raise QueryRefused(
            f"refused: {len(statements)} statements ({kinds}); exactly one is allowed "
            f"({_WHAT_IS_ALLOWED})"
        )
    (statement,) = statements
    kind = _kind(statement)
    if kind == "EXPLAIN":
        try:
            check_read_only(_explained(statement.query))
        except QueryRefused as exc:
            reason = str(exc).removeprefix("refused: ")
            raise QueryRefused(f"refused: under EXPLAIN, {reason}") from exc
        except duckdb.ParserException as exc:
            raise QueryRefused(
                f"refused: EXPLAIN of a statement not recognised as one SELECT ({_WHAT_IS_ALLOWED})"
            ) from exc
    elif kind != "SELECT":
        raise QueryRefused(
            f"refused: {_label(statement)} statements are not allowed ({_WHAT_IS_ALLOWED})"
        )
    return statement


def run_query(sql: str, *, data: DataRoot) -> pl.DataFrame:
    """Run one read-only statement against a snapshot of the warehouse.

    Raises :class:`QueryRefused` for anything but one ``SELECT`` (or ``EXPLAIN`` of one),
    and when the statement reaches for a file outside the lake or a setting; other SQL
    errors are DuckDB's own. A nightly run landing at the same time is not disturbed.
    """
    statement = check_read_only(sql)
    con = open_reader(data, sandbox=True)
    try:
        relation = con.sql(statement)
        return pl.DataFrame() if relation is None else relation.pl()
    except duckdb.PermissionException as exc:
        reason = " ".join(str(exc).split()).removeprefix("Permission Error: Cannot")
        raise QueryRefused(
            f"refused: cannot{reason} (read-only audit interface: only the warehouse and "
            f"{data.lake} are readable)"
        ) from exc
    except duckdb.InvalidInputException as exc:
        if "configuration has been locked" not in str(exc):
            raise
        reason = " ".join(str(exc).split()).removeprefix("Invalid Input Error: ")
        raise QueryRefused(f"refused: {reason} ({_WHAT_IS_ALLOWED})") from exc
    finally:
        con.close()


def format_result(frame: pl.DataFrame, output: OutputFormat) -> str:
    """Render a query result for people (``table``) or programs (``csv``, ``json``).

    The table shows every column, at full width and with whole strings (paths, hashes);
    rows beyond 200 are elided in the middle, the shape line gives the count.
    """
    if output == "csv":
        return frame.write_csv()
    if output == "json":
        buffer = io.StringIO()
        buffer.write(json.dumps(frame.to_dicts(), default=str, indent=None))
        buffer.write("\n")
        return buffer.getvalue()
    with pl.Config(
        tbl_rows=200,
        tbl_cols=-1,
        fmt_str_lengths=10_000,
        tbl_width_chars=-1,
        tbl_hide_dataframe_shape=False,
    ):
        return f"{frame}\n"

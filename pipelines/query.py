"""``ropeload query``: read-only SQL on the published warehouse, read-only in fact.

Two independent fences, each enough against the escapes a keyword filter misses
(``COPY ... TO``, ``ATTACH``, ``EXPORT DATABASE``, ``select 1; copy ...``, ``SET``,
``PRAGMA``, ``read_csv('/etc/passwd')``):

1. :func:`check_read_only`: DuckDB's own parser (``duckdb.extract_statements``) must
   find exactly one statement, of type ``SELECT`` (which covers ``WITH ... SELECT``,
   ``FROM t``, ``VALUES``, ``DESCRIBE``, ``SHOW``, ``SUMMARIZE``) or ``EXPLAIN`` of one
   such statement, and its parse tree (``json_serialize_sql``) must hold queries only:
   DuckDB also calls ``WITH x AS (COPY ... TO ...) SELECT 1`` a ``SELECT`` (or an
   ``INSERT``, ``UPDATE``, ``DELETE ... RETURNING`` in the ``WITH``). Anything else is
   refused before a connection to the warehouse is opened.
2. The statement runs on :func:`warehouse.store.open_reader` with ``sandbox=True``: the
   warehouse attached read-only, no file outside ``<data>/lake`` reachable, extensions
   off, configuration locked. A file function pointed outside the lake fails there and
   is reported as a refusal too.
"""

from __future__ import annotations

import io
import json
import math
import re
from collections.abc import Callable, Iterator
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
    return [(start, text) for start, text, _ in _typed_tokens(sql)]


def _typed_tokens(sql: str) -> list[tuple[int, str, duckdb.token_type]]:
    """(offset, text, type) of the tokens of ``sql``, comments left out."""
    spans = duckdb.tokenize(sql)
    tokens = []
    for k, (start, kind) in enumerate(spans):
        end = spans[k + 1][0] if k + 1 < len(spans) else len(sql)
        if kind != duckdb.token_type.comment:
            tokens.append((start, sql[start:end].strip(), kind))
    return tokens


def _explained(sql: str) -> list[str]:
    """The statement under ``EXPLAIN [ANALYZE] [(options)]`` (``sql`` starts with EXPLAIN),
    in both readings of a leading bracket: DuckDB's options (``(FORMAT JSON) SELECT 1``)
    or the statement's own first query (``(SELECT 1) UNION (SELECT 2)``). Each reading
    that parses must be read-only (:func:`check_read_only`)."""
    tokens = _typed_tokens(sql)[1:]
    if tokens and tokens[0][1].upper() in ("ANALYZE", "ANALYSE"):
        tokens = tokens[1:]
    if not tokens:
        return []
    readings = [sql[tokens[0][0] :]]
    if tokens[0][1].startswith("("):
        depth = 0
        while tokens:
            _, text, kind = tokens.pop(0)
            # only operators carry brackets: one in a string ('(', $$($$, E'(') or a
            # quoted name ("(") is text, and counting it moved the options' end
            if kind == duckdb.token_type.operator:
                depth += text.count("(") - text.count(")")
            if depth <= 0:
                break
        if tokens:
            readings.append(sql[tokens[0][0] :])
    return readings


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
        parsed = 0
        for reading in _explained(statement.query):
            try:
                check_read_only(reading)
            except QueryRefused as exc:
                reason = str(exc).removeprefix("refused: ")
                raise QueryRefused(f"refused: under EXPLAIN, {reason}") from exc
            except duckdb.ParserException:
                continue  # not this reading (DuckDB's parse of the whole has one that is)
            parsed += 1
        if not parsed:
            raise QueryRefused(
                f"refused: EXPLAIN of a statement not recognised as one SELECT ({_WHAT_IS_ALLOWED})"
            )
    elif kind != "SELECT":
        raise QueryRefused(
            f"refused: {_label(statement)} statements are not allowed ({_WHAT_IS_ALLOWED})"
        )
    else:
        _check_query_nodes(statement.query)
    return statement


#: Query nodes of a read-only statement. DuckDB parses ``WITH x AS (COPY ... TO ...)
#: SELECT 1`` (also an INSERT, UPDATE or DELETE ... RETURNING there) as a ``SELECT``
#: statement, and runs it: the COPY writes its file, in the lake too (the sandbox's
#: allowed directory).
_READ_ONLY_NODES = frozenset(
    ("SELECT_NODE", "SET_OPERATION_NODE", "RECURSIVE_CTE_NODE", "CTE_NODE")
)


def _query_nodes(tree: object) -> Iterator[str]:
    """The types of the query nodes (``SELECT_NODE``, ``COPY_QUERY_NODE``) in a parse tree."""
    if isinstance(tree, dict):
        kind = tree.get("type")
        if isinstance(kind, str) and kind.endswith("_NODE"):
            yield kind
        for value in tree.values():
            yield from _query_nodes(value)
    elif isinstance(tree, list):
        for value in tree:
            yield from _query_nodes(value)


def _check_query_nodes(sql: str) -> None:
    """Refuse a ``SELECT`` statement any of whose query nodes is not a query (a COPY,
    INSERT, UPDATE or DELETE in its WITH clause): DuckDB's own parse tree, as JSON."""
    con = duckdb.connect(":memory:")
    try:
        (tree,) = con.execute("SELECT json_serialize_sql(?)", [sql]).fetchone()
    finally:
        con.close()
    parsed = json.loads(tree)
    if parsed.get("error"):
        raise QueryRefused(
            f"refused: a statement DuckDB cannot show as a parse tree "
            f"({parsed.get('error_message', '')}; {_WHAT_IS_ALLOWED})"
        )
    for node in _query_nodes(parsed):
        if node not in _READ_ONLY_NODES:
            what = node.removesuffix("_NODE").removesuffix("_QUERY").replace("_", " ")
            raise QueryRefused(
                f"refused: {what} inside WITH (a SELECT that writes); not allowed "
                f"({_WHAT_IS_ALLOWED})"
            )


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
        return pl.DataFrame() if relation is None else _to_polars(relation)
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


#: DuckDB types every reader of a result takes as they are; a result column of any other
#: type that polars cannot take (an INTERVAL, a UNION, a date at infinity) is shown as
#: DuckDB writes it as text.
_PLAIN_TYPES = frozenset(
    "BOOLEAN TINYINT SMALLINT INTEGER BIGINT HUGEINT UTINYINT USMALLINT UINTEGER UBIGINT "
    "FLOAT DOUBLE VARCHAR".split()
)


#: DuckDB types polars takes wrongly or only by panicking (a UHUGEINT as a negative
#: decimal, a BIT as its internal bytes, an INTERVAL inside a list or struct, panicking
#: on the way), or that its CSV writer refuses (a BLOB): a column whose type holds one is
#: DuckDB's text from the start (a BLOB as DuckDB's escaped bytes, ``a\x00b``). DuckDB
#: 2.0's VARIANT, BIGNUM and GEOMETRY reach polars as Arrow extension types holding their
#: internal bytes (the CSV writer refuses them; ``duckdb_settings().typed_value`` is one).
_TEXT_TYPES = re.compile(r"\b(UHUGEINT|BIT|INTERVAL|UNION|BLOB|VARIANT|BIGNUM|GEOMETRY)\b")
#: A HUGEINT polars holds as a 38-digit decimal: beyond it, Python's copy is rounded.
_DECIMAL_DIGITS = 38


def _to_polars(relation: duckdb.DuckDBPyRelation) -> pl.DataFrame:
    """The result as a polars frame; where polars cannot take a column's values, the
    columns of other than plain types as DuckDB's text."""
    kinds = [str(kind) for kind in relation.types]  # by position: names may repeat
    if any(_TEXT_TYPES.search(kind) for kind in kinds):
        relation = _as_text(relation, lambda i, kind: bool(_TEXT_TYPES.search(kind)))
    try:
        frame = relation.pl()
        wide = {
            i
            for i, kind in enumerate(kinds)
            if kind == "HUGEINT" and _beyond_digits(frame.to_series(i).to_physical())
        }
        beyond = {i for i in range(frame.width) if _series_beyond(frame.to_series(i))}
        if not wide | beyond:
            return frame
        # only those columns as text: the others (a list, a timestamp) keep their types
        return _as_text(relation, lambda i, kind: i in wide | beyond).pl()
    except pl.exceptions.PolarsError:
        pass
    except BaseException as exc:  # pyo3's PanicException
        if type(exc).__name__ != "PanicException":
            raise
    return _as_text(relation, lambda i, kind: kind.split("(")[0] not in _PLAIN_TYPES).pl()


def _as_text(
    relation: duckdb.DuckDBPyRelation, text: Callable[[int, str], bool]
) -> duckdb.DuckDBPyRelation:
    """``relation`` with the columns ``text(position, type)`` picks cast to DuckDB's text,
    each column taken by its position (a result may repeat a name)."""
    columns = []
    for i, (name, kind) in enumerate(zip(relation.columns, relation.types, strict=True)):
        quoted = '"' + name.replace('"', '""') + '"'
        column = f"#{i + 1}"
        picked = text(i, str(kind))
        columns.append(
            f"CAST({column} AS VARCHAR) AS {quoted}" if picked else f"{column} AS {quoted}"
        )
    return relation.project(", ".join(columns))


def _beyond_digits(physical: pl.Series) -> bool:
    """Whether a HUGEINT column's values (polars' Int128) go beyond 38 digits."""
    if physical.dtype != pl.Int128:
        return False
    limit = 10**_DECIMAL_DIGITS
    return bool(((physical >= limit) | (physical <= -limit)).any())


#: Python's dates, 0001-01-01 to 9999-12-31, in days and seconds from 1970-01-01.
_DAYS = (-719_162, 2_932_896)
_SECONDS = (-62_135_596_800, 253_402_300_799)
_PER_SECOND = {"ns": 10**9, "us": 10**6, "ms": 10**3}


def _series_beyond(series: pl.Series) -> bool:
    """Whether a date or time value, in the column or inside a list, array, struct or map,
    lies where no Python date can (DuckDB's ``infinity``): polars holds it, and panics
    when asked to show it."""
    kind = series.dtype
    if isinstance(kind, pl.Map):  # as its entries: a list of key-value structs
        entries = pl.List(pl.Struct({"key": kind.key, "value": kind.value}))
        return _series_beyond(series.cast(entries))
    if isinstance(kind, pl.List | pl.Array):
        inner = series.list.explode() if isinstance(kind, pl.List) else series.arr.explode()
        return _series_beyond(inner)
    if isinstance(kind, pl.Struct):
        return any(_series_beyond(field) for field in series.struct.unnest().iter_columns())
    if kind == pl.Date:
        low, high = _DAYS
    elif isinstance(kind, pl.Datetime):
        per = _PER_SECOND[kind.time_unit or "us"]
        # int64 nanoseconds (1677-2262) all lie within Python's dates
        low, high = max(_SECONDS[0] * per, -(2**63)), min(_SECONDS[1] * per, 2**63 - 1)
    else:
        return False
    physical = series.to_physical()
    return bool(((physical < low) | (physical > high)).any())


def _finite(value: object) -> object:
    """``value`` with every NaN or infinite float inside it as None (JSON has neither).
    Decimals stay exact, as text (``default=str``), as DuckDB's own CLI writes them."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def format_result(frame: pl.DataFrame, output: OutputFormat) -> str:
    """Render a query result for people (``table``) or programs (``csv``, ``json``).

    The table shows every column, at full width and with whole strings (paths, hashes);
    rows beyond 200 are elided in the middle, the shape line gives the count. CSV writes
    a nested value (list, struct, map) as its JSON text; JSON is strict (NaN and
    infinities as null; a DECIMAL or HUGEINT exact, as text, as DuckDB's CLI writes it).
    """
    if output == "csv":  # a nested value (list, struct, map) as its JSON text
        nested = [c for c, t in frame.schema.items() if t.is_nested()]
        flat = frame.with_columns(
            pl.Series(c, [json.dumps(_finite(v), default=str) for v in frame[c].to_list()])
            for c in nested
        )
        return flat.write_csv()
    if output == "json":  # strict JSON: NaN and infinities as null
        buffer = io.StringIO()
        rows = _finite(frame.to_dicts())
        buffer.write(json.dumps(rows, default=str, indent=None, allow_nan=False))
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

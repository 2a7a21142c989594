#!/usr/bin/env python3
"""Puts the rows the tests measured into the tables of README.md and docs/**/*.md.

Each table sits between `<!-- test-table NAME begin -->` and `<!-- test-table NAME end -->`.
The tests write one row per case to target/test-output/readme/NAME/ (`common::readme_row`):
`cargo test --test NAME` the `stress`, `reference`, `cellproj` and `iso` tables, and
`cargo run --example readme_pictures` the `shells` table's rows as it draws the pictures.
Each table's rows are replaced by the measured ones, keeping the file's order of cases and
appending new ones; every markdown file that holds a table's markers gets them. A table whose
folder does not exist (its test has not run) is left as it is, and said so; a case of the table without a measured row fails. A caption under each table
says when (the newest row's date, UTC) and on what machine (this one's CPU, where the tests ran;
the GPU modes ran on the adapter `tetvr gpu-info` names there).
"""
import datetime
import pathlib
import re
import sys

from doc_tables import fill, root

rows_root = root / "target" / "test-output" / "readme"
marker = re.compile(r"<!-- test-table (\S+) begin -->\n(.*?)<!-- test-table \1 end -->", re.S)


def case_of(row):
    return row.split("|")[1].strip()


def machine():
    cpuinfo = pathlib.Path("/proc/cpuinfo")
    text = cpuinfo.read_text() if cpuinfo.exists() else ""
    models = [l.split(":", 1)[1].strip() for l in text.splitlines() if l.startswith("model name")]
    return f"{models[0]}, {len(models)} cores" if models else "an unknown machine"


def caption(files):
    newest = max(f.stat().st_mtime for f in files)
    day = datetime.datetime.fromtimestamp(newest, datetime.timezone.utc).date()
    return f"Measured {day} on {machine()}."


def table(name, old):
    rows_dir = rows_root / name
    if not rows_dir.is_dir():
        print(f"{name}: no rows in {rows_dir.relative_to(root)} (run its test first), kept")
        return old
    measured = {}
    files = sorted(rows_dir.glob("*.md"))
    for f in files:
        row = f.read_text().strip()
        measured[case_of(row)] = row
    lines = [line for line in old.strip("\n").split("\n") if line.startswith("|")]
    header, body = lines[:2], lines[2:]
    order = [case_of(line) for line in body]
    missing = [case for case in order if case not in measured]
    if missing:
        sys.exit(f"{name}: no measured row for {missing}: run its test first")
    order += sorted(case for case in measured if case not in order)
    print(f"{name}: {len(order)} rows from {rows_dir.relative_to(root)}")
    rows = header + [measured[case] for case in order]
    return "\n".join(rows + ["", caption(files)]) + "\n"


def replace(m):
    name = m.group(1)
    return f"<!-- test-table {name} begin -->\n{table(name, m.group(2))}<!-- test-table {name} end -->"


fill(marker, replace, "test tables")

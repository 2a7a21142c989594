#!/usr/bin/env python3
"""Puts the rows the tests measured into the README's tables.

Each table sits between `<!-- test-table NAME begin -->` and `<!-- test-table NAME end -->`.
The tests write one row per case to target/test-output/readme/NAME/ (`common::readme_row`):
`cargo test --test NAME` the `stress`, `reference`, `cellproj` and `iso` tables, and
`cargo run --example readme_pictures` the `shells` table's rows as it draws the pictures. Each table's rows are replaced by the measured ones, keeping the README's order of cases and
appending new ones. A table whose folder does not exist (its test has not run) is left as it
is, and said so; a case of the table without a measured row fails.
"""
import pathlib
import re
import sys

root = pathlib.Path(__file__).resolve().parent.parent
rows_root = root / "target" / "test-output" / "readme"
readme = root / "README.md"
marker = re.compile(r"<!-- test-table (\S+) begin -->\n(.*?)<!-- test-table \1 end -->", re.S)


def case_of(row):
    return row.split("|")[1].strip()


def table(name, old):
    rows_dir = rows_root / name
    if not rows_dir.is_dir():
        print(f"{name}: no rows in {rows_dir.relative_to(root)} (run its test first), kept")
        return old
    measured = {}
    for f in sorted(rows_dir.glob("*.md")):
        row = f.read_text().strip()
        measured[case_of(row)] = row
    lines = old.strip("\n").split("\n")
    header, body = lines[:2], lines[2:]
    order = [case_of(line) for line in body]
    missing = [case for case in order if case not in measured]
    if missing:
        sys.exit(f"{name}: no measured row for {missing}: run its test first")
    order += sorted(case for case in measured if case not in order)
    print(f"{name}: {len(order)} rows from {rows_dir.relative_to(root)}")
    return "\n".join(header + [measured[case] for case in order]) + "\n"


def replace(m):
    name = m.group(1)
    return f"<!-- test-table {name} begin -->\n{table(name, m.group(2))}<!-- test-table {name} end -->"


readme.write_text(marker.sub(replace, readme.read_text()))

#!/usr/bin/env python3
"""Puts the stress suite's measured rows into the README's table.

`cargo test --test stress` writes one row per case to target/test-output/stress/; this replaces
the rows of the README table between the `stress-table` markers with them, keeping the README's
order of cases and appending new ones. Fails if a case of the table has no measured row.
"""
import pathlib
import sys

root = pathlib.Path(__file__).resolve().parent.parent
rows_dir = root / "target" / "test-output" / "stress"
readme = root / "README.md"

measured = {}
for f in sorted(rows_dir.glob("*.md")):
    row = f.read_text().strip()
    measured[row.split("|")[1].strip()] = row

text = readme.read_text()
begin, end = "<!-- stress-table begin -->", "<!-- stress-table end -->"
head, rest = text.split(begin)
table, tail = rest.split(end)
lines = table.strip("\n").split("\n")
header, body = lines[:2], lines[2:]
order = [line.split("|")[1].strip() for line in body]
missing = [case for case in order if case not in measured]
if missing:
    sys.exit(f"no measured row for {missing}: run `cargo test --test stress` first")
order += sorted(case for case in measured if case not in order)
new_table = "\n".join(header + [measured[case] for case in order])
readme.write_text(f"{head}{begin}\n{new_table}\n{end}{tail}")
print(f"README: {len(order)} stress rows from {rows_dir.relative_to(root)}")

#!/usr/bin/env python3
"""Puts `tetvr bench` results into the tables of README.md and docs/**/*.md.

Each table sits between two markers that say where its figures come from:

    <!-- bench-table csv=docs/bench/h200/real-512/bench.csv,docs/bench/h200/grids-1024/bench.csv
         view=outside bytes=raycast:partial lists cols=shells:samples 512|raycast:partial lists -->
    ...generated rows...
    <!-- bench-table end -->

One row per scene (and view, where `view=` is not given) in the CSVs' order, one column per
`mode:setting` of `cols` (separated by `|`), each cell "median ms, PSNR dB" of that bench row,
then, with `bytes=mode:setting`, that row's GPU bytes per tet (its `bytes_per_tet` column where
the mode reports one, else GPU memory over tets). A column's setting `*` takes the mode's row of
any setting (the textured cage's reference is not "exact f64"). With `mb=mode:setting`, that
row's GPU memory in MB (10^6 bytes, textures included); with `deform=mode:setting`, that row's
`deform` plus `update` stages (a deforming scene's positions computed and uploaded each frame;
"–" for a static scene). A caption line under the table names the adapter,
machine, date, runs and image sizes, all read from the CSVs. Fails when a CSV is missing or a
column matches no row at all; a scene without a row for a column shows "–".

With `skips=shells:samples 512` instead of `cols=`, the table has a row per skip turned off (each
`samples 512, no SKIP` bench row): its time and PSNR beside those of the row with every skip on
(`shells:samples 512`) of the same scene and view, and the speedup the skip gives.
"""
import csv
import re
import sys

from doc_tables import fill, root

marker = re.compile(r"<!-- bench-table (csv=.*?) -->\n(.*?)<!-- bench-table end -->", re.S)


def spec_of(text):
    """key=value pairs (csv, view, bytes, cols); a value runs to the next " key=" (values hold
    spaces: "raycast:partial lists")."""
    text = " ".join(text.split())
    spec = dict(re.findall(r"(\w+)=(.*?)(?= \w+=|$)", text))
    if "cols" in spec:
        spec["cols"] = [c.split(":", 1) for c in spec["cols"].split("|")]
    return spec


def rows_of(paths):
    rows = []
    for path in paths.split(","):
        with open(root / path, newline="") as f:
            rows += list(csv.DictReader(f))
    return rows


def cell(row):
    if row is None:
        return "–"
    ms = float(row["median_ms"])
    ms = f"{ms:.3g}" if ms < 100 else f"{ms:.0f}"
    psnr = row["psnr_db"]
    return f"{ms} ms, {float(psnr):.1f} dB" if psnr not in ("", "inf") else f"{ms} ms"


def bytes_per_tet(row, tets):
    if row is None:
        return "–"
    if row.get("bytes_per_tet"):
        return row["bytes_per_tet"]
    return f"{int(row['gpu_bytes']) / int(tets):.0f}" if row["gpu_bytes"] else "–"


def mb(row):
    return "–" if row is None or not row["gpu_bytes"] else f"{int(row['gpu_bytes']) / 1e6:.1f}"


def deform_ms(row):
    if row is None:
        return "–"
    stages = dict(kv.split("=") for kv in row["stages_ms"].split(";") if "=" in kv)
    if "deform" not in stages:
        return "–"
    return f"{float(stages['deform']) + float(stages.get('update', 0)):.3g} ms"


def find(rows, scene, view, mode, setting):
    """The row of scene, view, mode and setting (any setting of the mode for `*`)."""
    for r in rows:
        if (r["scene"], r["view"], r["mode"]) == (scene, view, mode) and setting in ("*", r["setting"]):
            return r
    return None


def caption(rows, spec):
    first = rows[0]
    runs = sorted({r["runs"] for r in rows})
    dates = sorted({r["date"] for r in rows})
    sizes = sorted({f"{r['width']}x{r['height']}" for r in rows})
    return (
        f"Medians of {'/'.join(runs)} runs at {', '.join(sizes)}; {first['adapter']}; "
        f"{first['machine']}; {', '.join(dates)}; from `{spec['csv']}`."
    )


def skips_table(spec):
    """Each skip's row beside the all-skips-on row of the same scene and view."""
    rows = rows_of(spec["csv"])
    mode, setting = spec["skips"].split(":", 1)
    on = {(r["scene"], r["view"]): r for r in rows if (r["mode"], r["setting"]) == (mode, setting)}
    prefix = f"{setting}, no "
    offs = [r for r in rows if r["mode"] == mode and r["setting"].startswith(prefix)]
    if not offs:
        sys.exit(f"bench-table: no '{prefix}...' rows in {spec['csv']}")
    head = ["skip turned off", "scene", "view", "all skips on", "skip off", "speedup"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for off in offs:
        base = on.get((off["scene"], off["view"]))
        if base is None:
            continue
        speedup = float(off["median_ms"]) / float(base["median_ms"])
        cells = [off["setting"][len(prefix):], off["scene"], off["view"], cell(base), cell(off)]
        lines.append("| " + " | ".join(cells + [f"{speedup:.2f}x"]) + " |")
    return "\n".join(lines + ["", caption(rows, spec)]) + "\n"


def table(spec):
    if "skips" in spec:
        return skips_table(spec)
    rows = rows_of(spec["csv"])
    view = spec.get("view")
    if view:
        rows = [r for r in rows if r["view"] == view]
    keys = []
    for r in rows:
        key = (r["scene"], r["view"], r["tets"], f"{r['width']}x{r['height']}")
        if key not in keys:
            keys.append(key)
    for mode, setting in spec["cols"]:
        if not any(r["mode"] == mode and setting in ("*", r["setting"]) for r in rows):
            sys.exit(f"bench-table: no row for {mode}:{setting} in {spec['csv']}")
    of = lambda key: spec[key].split(":", 1) if key in spec else None
    per_tet_of, mb_of, deform_of = of("bytes"), of("mb"), of("deform")
    head = ["scene", "tets", "size"] + ([] if view else ["view"])
    head += [f"{m} {s}" if s != "*" else m for m, s in spec["cols"]]
    head += [f"{per_tet_of[0]} {per_tet_of[1]}: bytes per tet"] if per_tet_of else []
    head += [f"{mb_of[0]} {mb_of[1]}: GPU MB"] if mb_of else []
    head += [f"{deform_of[0]} {deform_of[1]}: deform + update"] if deform_of else []
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for scene, v, tets, size in keys:
        cells = [scene, f"{int(tets):,}", size] + ([] if view else [v])
        cells += [cell(find(rows, scene, v, m, s)) for m, s in spec["cols"]]
        if per_tet_of:
            cells.append(bytes_per_tet(find(rows, scene, v, *per_tet_of), tets))
        if mb_of:
            cells.append(mb(find(rows, scene, v, *mb_of)))
        if deform_of:
            cells.append(deform_ms(find(rows, scene, v, *deform_of)))
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", caption(rows, spec)]
    return "\n".join(lines) + "\n"


def replace(m):
    return f"<!-- bench-table {m.group(1)} -->\n{table(spec_of(m.group(1)))}<!-- bench-table end -->"


fill(marker, replace, "bench tables")

"""The markdown files whose generated tables `bench-table.py` and `test-tables.py` fill."""

import pathlib

root = pathlib.Path(__file__).resolve().parent.parent
documents = [root / "README.md"] + sorted((root / "docs").rglob("*.md"))


def fill(marker, replace, kind):
    """Replaces every `marker` match in the documents by `replace(match)`; writes a file only
    when its text changes and prints each file's count of `kind` tables."""
    for doc in documents:
        text = doc.read_text()
        new, count = marker.subn(replace, text)
        if count == 0:
            continue
        if new != text:
            doc.write_text(new)
        print(f"{doc.relative_to(root)}: {count} {kind}{'' if new != text else ', unchanged'}")

"""The example scripts' page, generated at build time (mkdocs-gen-files): one section per
``examples/*.py``, made of its docstring, its picture ``docs/examples/<name>.png`` when there
is one, and its source. A new example appears without touching this script or mkdocs.yml.

A hand-written ``docs/examples/index.md`` takes precedence: then nothing is generated.

An example writes its picture to ``outputs/examples/`` (untracked) unless given a path:
``python examples/NAME.py docs/examples/NAME.png`` refreshes the page's.
"""

import ast
from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
PICTURES = ROOT / "docs" / "examples"
PAGE = "examples/index.md"


def section(script: Path) -> str:
    source = script.read_text(encoding="utf-8")
    doc = ast.get_docstring(ast.parse(source)) or ""
    title, _, body = doc.partition("\n")
    lines = [f"## {script.stem}: {title.rstrip('.')}", "", body.strip(), ""]
    picture = PICTURES / f"{script.stem}.png"
    if picture.is_file():
        lines += [f"![{title}]({picture.name})", ""]
    lines += [f'??? example "examples/{script.name}"', "", "    ```python"]
    lines += [f"    {line}" if line else "" for line in source.rstrip("\n").split("\n")]
    lines += ["    ```", ""]
    return "\n".join(lines)


if not (PICTURES / "index.md").is_file():
    scripts = sorted(EXAMPLES.glob("[!_]*.py")) if EXAMPLES.is_dir() else []
    intro = ("# Example scripts\n\n"
             "Each script in `examples/` is a short, importable program on the library. From the "
             "repository root, `python examples/<name>.py` runs its full case. The test suite runs "
             "each script's small case (`main(small=True)`) and checks its numbers and its picture "
             "(`tests/test_examples.py`). Each docstring says what both cases are and how long "
             "they take.\n\n")
    if not scripts:
        intro += "No example scripts in this checkout.\n"
    with mkdocs_gen_files.open(PAGE, "w") as page:
        page.write(intro + "\n".join(section(s) for s in scripts))
    mkdocs_gen_files.set_edit_path(PAGE, Path("examples"))

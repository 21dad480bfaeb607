"""The API reference, generated at build time (mkdocs-gen-files): one page per module of the
``metasheet`` package, found by walking its folder, so a module that moves or appears (a new
package) is documented without touching this script or ``mkdocs.yml``.

The walk is static (files, not imports): mkdocstrings' griffe reads the sources, nothing is
imported, so a module whose optional dependency is missing is documented all the same.
Private modules (a leading underscore) and ``__main__`` are left out; a package's page shows
its docstring (its map of modules), each module's page its public members.
"""

from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "metasheet"

nav = mkdocs_gen_files.Nav()

for path in sorted(PACKAGE.rglob("*.py")):
    module = path.relative_to(ROOT).with_suffix("")
    parts = tuple(module.parts)
    if "__pycache__" in parts or any(p.startswith("_") and p != "__init__" for p in parts):
        continue
    if parts[-1] == "__init__":
        parts = parts[:-1]
        doc_path = Path(*parts, "index.md")
        options = "    options:\n      members: false\n"
    else:
        doc_path = Path(*parts).with_suffix(".md")
        options = ""
    nav[parts] = doc_path.as_posix()
    identifier = ".".join(parts)
    with mkdocs_gen_files.open(Path("reference", doc_path), "w") as fd:
        fd.write(f"::: {identifier}\n{options}")
    mkdocs_gen_files.set_edit_path(Path("reference", doc_path), path.relative_to(ROOT))

with mkdocs_gen_files.open("reference/SUMMARY.md", "w") as nav_file:
    nav_file.writelines(nav.build_literate_nav())

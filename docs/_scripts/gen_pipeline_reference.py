"""The pipeline-file reference page, generated at build time (mkdocs-gen-files) from the
parameter models: :func:`metasheet.pipeline.reference.pipeline_reference`."""

import mkdocs_gen_files

from metasheet.pipeline.reference import pipeline_reference

with mkdocs_gen_files.open("pipeline-keys.md", "w") as fh:
    fh.write(pipeline_reference())

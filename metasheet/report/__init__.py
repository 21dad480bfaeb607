"""The report of a pipeline run (``report/report.md``): :func:`.build.build_report` assembles
it from each stage's summary, one module per section (the constants, the model comparison, the
mesh convergence, the reduced model, the printed sheet, the design, the uncertainty, the two
columns of the paper's figures, the sibling pipelines' outputs). Pure functions of the
summaries: the report stage (:mod:`metasheet.pipeline.stages.report`) reads the files."""

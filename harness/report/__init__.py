"""Statistics (Wilson and bootstrap intervals, paired tests), the Markdown report and its
plots, and the self-contained HTML report (:mod:`harness.report.html`), from results files.
Both reports render one report built as data (:mod:`harness.report.document`).

May import: :mod:`harness.runner` (results), :mod:`conceptfusion` base modules.
"""

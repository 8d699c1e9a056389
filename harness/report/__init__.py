"""Statistics (Wilson and bootstrap intervals, paired tests), the Markdown report and its
plots, from results files.

May import: :mod:`harness.runner` (results), :mod:`conceptfusion` base modules.
"""

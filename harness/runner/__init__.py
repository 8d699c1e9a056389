"""Running suites: suite definitions, the one job model (episode and map jobs), the
backends that run jobs (serial, process pool, Ray), and the JSON Lines results with resume.

May import: :mod:`agents`, :mod:`sim_envs`, :mod:`conceptfusion`, :mod:`harness.maps`,
:mod:`harness.replay.record` (episode recordings) and :mod:`harness.report.paths` (their file names).
"""

"""The evaluation harness and the ``cfharness`` command line: the only place that joins an
environment and an agent.

* :mod:`harness.runner` - suites, jobs, backends (serial, process pool, Ray), results files;
* :mod:`harness.maps` - the map suites (query, ablation, spatial) scored against ground truth;
* :mod:`harness.report` - statistics, Markdown report and plots;
* :mod:`harness.demo` - the quick mapping demo.

May import: everything else of the project.
"""

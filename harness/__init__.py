"""The evaluation harness and the ``cfharness`` command line: the only place that joins an
environment and an agent.

* :mod:`harness.runner` - suites, jobs, backends (serial, process pool, Ray), results files;
* :mod:`harness.maps` - the map suites (query, ablation, spatial) scored against ground truth;
* :mod:`harness.report` - statistics, Markdown report and plots;
* :mod:`harness.replay` - episode recordings and their videos;
* :mod:`harness.viewer` - ``cfharness view``: a map in the browser, with text, click and image queries;
* :mod:`harness.demo` - the quick mapping demo.

May import: everything else of the project.
"""

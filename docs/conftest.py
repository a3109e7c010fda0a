"""pytest collection of docs/: the markdown pages and gen_api.py are doctests; the Sphinx
configuration, its extensions and the build output are not test modules."""

collect_ignore = ["conf.py", "_ext"]
collect_ignore_glob = ["_build/*", "examples/*", "reference/*"]

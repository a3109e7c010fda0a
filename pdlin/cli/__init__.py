"""The ``pdlin`` command line (:func:`pdlin.cli.main.main`)."""

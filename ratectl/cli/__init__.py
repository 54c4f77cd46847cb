"""The ``ratectl`` command (:mod:`~ratectl.cli.main`) and its demo (:mod:`~ratectl.cli.demo`)."""

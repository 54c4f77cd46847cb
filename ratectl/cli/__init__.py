"""The ``ratectl`` command (`main`) and its demo (`demo`)."""

"""Sources, sinks, configuration, the simulator and the ``fisheye-des`` command line."""

"""The launchers: the ``darwin`` command line and what it starts (the daemon, ``darwin up``, the
router, the boot service, child processes and their logins). They compose the engine
(:mod:`robot_daemon.engine`) and the adapters; nothing in the engine imports them."""

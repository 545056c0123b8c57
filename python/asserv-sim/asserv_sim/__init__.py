"""asserv_sim: the compiled simulator behind ``asserv[sim]`` (``asserv_sim._core``) and its data.

``field/`` and ``scenarios/`` are package data, found with ``importlib.resources``; importing
this package does not load the extension (``asserv.sim`` does, through ``asserv.sim._core``).
"""

"""The asyncio driver, :class:`~pywsg.client.AsyncGripper`. **Edit here**: ``commands.py`` is the one
source of the command methods; ``scripts/unasync_client.py`` generates
``pywsg/client/_sync/generated_commands.py`` from it (the test suite fails when it is stale).

``gripper.py`` the shell (I/O: send, wait, time out, reconnect, streams), ``commands.py`` one method
per command, ``handles.py`` what calls hand back (``AsyncMotion``, ``AsyncStream``), ``transport.py``
TCP, UDP and serial on the event loop. Import from :mod:`pywsg.client`, not from here.
"""

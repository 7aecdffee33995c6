"""The blocking driver, :class:`~pywsg.client.Gripper`. ``generated_commands.py`` is **generated** from
``pywsg/client/_async/commands.py`` by ``scripts/unasync_client.py``: edit the source and run the
script. The rest is written by hand, because blocking I/O differs: ``gripper.py`` the shell (plain
sockets, the reading thread, the stream reader), ``handles.py`` (``Motion``, ``Stream``, the callback
thread), ``transport.py`` (TCP, UDP, serial). Import from :mod:`pywsg.client`, not from here.
"""

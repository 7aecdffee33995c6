"""Recorded traffic: the communication log a driver, proxy or CLI writes (:mod:`.commlog`) and the
captures, JSON-lines logs and hex dumps that ``wsg decode -f``, ``wsg replay`` and the cell-testing
toolkit read back as frames (:mod:`.reader`).

A library package below both ``cli/`` and ``testing/``: it depends on ``protocol/`` (and dpkt, loaded
only by :mod:`.reader`), never on a front end.
"""

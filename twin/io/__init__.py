"""File formats at the edge: everything here speaks mm and degrees and validates its input.

One reader and one validator for config files (:func:`twin.io.paths.read_toml`,
:class:`twin.io.table.Table`), one atomic writer (:mod:`twin.io.atomic`), one durable journal
(:mod:`twin.io.journal`); each file format in its own module.
"""

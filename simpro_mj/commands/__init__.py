"""The command line: one module per subcommand, argument parsing and wiring only.

:mod:`.main` builds the parser (``simpro-sim``) and turns every user mistake into
one line on stderr with exit status 2.
"""

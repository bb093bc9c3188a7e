"""Writer process of a run: ``python -m polydem_cli.io.writer_proc RESULT.h5`` (see :mod:`.hdf5`)."""

import sys

from .hdf5 import writer_main

if __name__ == "__main__":
    writer_main(sys.argv[1])

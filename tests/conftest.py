"""Test-session settings.

One BLAS/OpenMP thread per process, as ``make test`` sets: the suite starts process pools and a
Dask cluster, and with NumPy's and CasADi's default thread counts they oversubscribe this
2-core machine (the whole suite then takes ~3.5x longer). Set before NumPy is imported.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

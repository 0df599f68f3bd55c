#!/bin/bash
T=$1; C=$2; N=${3:-256}; S=${SCRIPT:-/tmp/icount.py}
P=/root/.pyenv/versions/3.11.7/bin/python
export XDG_CACHE_HOME=$C NUMBA_CPU_NAME=generic PYTHONPATH=$T PYTHONHASHSEED=0 OMP_NUM_THREADS=1
$P /tmp/gen/icount_hook_old.py $S $N 1 >/dev/null 2>&1 || echo FAIL
c1=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null $P /tmp/gen/icount_hook_old.py $S $N 1 2>&1 | grep Collected | awk '{print $4}')
c3=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null $P /tmp/gen/icount_hook_old.py $S $N 5 2>&1 | grep Collected | awk '{print $4}')
python -c "print('$T $RR_GEN', ($c3 - $c1) / (4 * $N))"

#!/bin/bash
# usage: ic.sh TREE CACHE [N]  -> instructions per robot env step (physics with record, generic build)
T=$1; C=$2; N=${3:-256}
export XDG_CACHE_HOME=$C NUMBA_CPU_NAME=generic PYTHONPATH=$T PYTHONHASHSEED=0 OMP_NUM_THREADS=1
/root/.pyenv/versions/3.11.7/bin/python /tmp/icount.py $N 1 >/dev/null 2>&1
c1=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null /root/.pyenv/versions/3.11.7/bin/python /tmp/icount.py $N 1 2>&1 | grep Collected | awk '{print $4}')
c3=$(valgrind --tool=callgrind --callgrind-out-file=/dev/null /root/.pyenv/versions/3.11.7/bin/python /tmp/icount.py $N 5 2>&1 | grep Collected | awk '{print $4}')
python -c "print('$T', ($c3 - $c1) / (4 * $N))"

for r in 1 2 3 4 5 6 7 8 9; do
for v in main mwt swt mswt; do
  if [ $v = main ]; then PP=/work/main; X=$HOME/.cache; else PP=/tmp/$v; X=/tmp/xdg-$v; fi
  for m in $1; do
  echo "$v $(PYTHONPATH=$PP XDG_CACHE_HOME=$X taskset -c 1 python tphys.py $m 4096 40 2>&1 | tail -1)"
  done
done; done

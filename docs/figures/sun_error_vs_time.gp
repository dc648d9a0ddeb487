# sun_error_vs_time.png from sun.csv, written by lightstage. Re-plot in this folder: gnuplot sun_error_vs_time.gp
set datafile separator comma
set table $s0 separator comma
plot 'sun.csv' using (column('cells_ms')):(column('cells_rmse')) with table
unset table
set table $s1 separator comma
plot 'sun.csv' using (column('flows_ms')):(column('flows_rmse')) with table
unset table
set table $s2 separator comma
plot 'sun.csv' using (column('sources_ms')):(column('sources_rmse')) with table
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'sun_error_vs_time.png'
set title 'Small source: error vs. time per frame, 128 px (set-up 84 ms, with the shape 1828)' font 'Sans,13'
set xlabel 'relight time per frame, ms'
set ylabel 'relative RMSE against ground truth'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.04, graph 0.06, graph 0.06
set logscale x
set xtics (0.5, 1, 2, 5, 10, 20, 50, 100)
set linetype 1 lc rgb '#0072B2' lw 2 pt 7 ps 1.4 dt 1
set linetype 2 lc rgb '#D55E00' lw 2 pt 5 ps 1.4 dt 2
set linetype 3 lc rgb '#009E73' lw 2 pt 9 ps 1.4 dt 3
set linetype 4 lc rgb '#CC79A7' lw 2 pt 13 ps 1.4 dt 4
set linetype 5 lc rgb '#E69F00' lw 2 pt 11 ps 1.4 dt 5
set linetype 6 lc rgb '#56B4E9' lw 2 pt 6 ps 1.4 dt 1
set linetype 7 lc rgb '#000000' lw 2 pt 4 ps 1.4 dt 2
set linetype 8 lc rgb '#8C564B' lw 2 pt 8 ps 1.4 dt 3
set linetype 9 lc rgb '#777777' lw 2 pt 12 ps 1.4 dt 4
set linetype 10 lc rgb '#0072B2' lw 2 pt 10 ps 1.4 dt 5
set linetype 11 lc rgb '#D55E00' lw 2 pt 1 ps 1.4 dt 1
set linetype 12 lc rgb '#009E73' lw 2 pt 2 ps 1.4 dt 2
set linetype 13 lc rgb '#CC79A7' lw 2 pt 3 ps 1.4 dt 3
set linetype cycle 13
plot $s0 using 1:2 with points lt 1 title 'LED cells', \
     $s1 using 1:2 with points lt 2 title 'source: flows alone', \
     $s2 using 1:2 with points lt 3 title 'source: flows + shape'

# temporal_error_vs_steps.png from temporal.csv, written by lightstage. Re-plot in this folder: gnuplot temporal_error_vs_steps.gp
set datafile separator comma
set table $s0 separator comma
plot 'temporal.csv' using (column('steps')):(column('render_rel_rms_error')):(strstrt(',0,1,2,3,4,', sprintf(',%d,', column(0))) == 0 ? '' : sprintf('%.0f us/px', 1 * column('temporal_fit_us_per_pixel'))) with table
unset table
set table $s1 separator comma
plot 'temporal.csv' using (column('steps')):(column('median_rate_rel_error')) with table
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'temporal_error_vs_steps.png'
set title 'Temporal fit: error against ground truth vs time steps (labels: temporal fit time per pixel)' font 'Sans,13'
set xlabel 'time steps over 600 s'
set ylabel 'relative error'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.14, graph 0.06, graph 0.06
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
plot $s0 using 1:2 with linespoints lt 1 title 'relit error', \
     $s0 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 1 notitle, \
     $s1 using 1:2 with linespoints lt 2 title 'median rate error'

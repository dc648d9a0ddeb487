# temporal_held_out_dark_dim_vs_steps.png from temporal_held_out_dark_dim.csv, written by lightstage. Re-plot in this folder: gnuplot temporal_held_out_dark_dim_vs_steps.gp
set datafile separator comma
set table $s0 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('temporal_fit')) with table
unset table
set table $s1 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('by_bic_alone')) with table
unset table
set table $s2 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('processes_only')) with table
unset table
set table $s3 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('step_fits_interpolated')) with table
unset table
set table $s4 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('linear_interpolation')) with table
unset table
set table $s5 separator comma
plot 'temporal_held_out_dark_dim.csv' using (column('captured_steps')):(column('nearest_step')) with table
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'temporal_held_out_dark_dim_vs_steps.png'
set title 'Held-out steps of the rise-and-fall scene 5x darker, its dim samples readmitted: relative error' font 'Sans,13'
set xlabel 'steps captured of 25 over 1200 s'
set ylabel 'relative RMS error'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.04, graph 0.06, graph 0.06
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
plot $s0 using 1:2 with linespoints lt 1 title 'temporal fit', \
     $s1 using 1:2 with linespoints lt 2 title 'models by BIC alone', \
     $s2 using 1:2 with linespoints lt 3 title 'processes only', \
     $s3 using 1:2 with linespoints lt 4 title 'per-step fits interpolated', \
     $s4 using 1:2 with linespoints lt 5 title 'photos: linear interpolation', \
     $s5 using 1:2 with linespoints lt 6 title 'photos: nearest captured step'

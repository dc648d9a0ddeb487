# scale_mpi_ranks.png from scale_mpi.csv, written by lightstage. Re-plot in this folder: gnuplot scale_mpi_ranks.gp
set datafile separator comma
set table $s0 separator comma
plot 'scale_mpi.csv' using (column('ranks')):(column('model_s')) with table
unset table
set table $s1 separator comma
plot 'scale_mpi.csv' using (column('ranks')):(column('io_floor_s')) with table
unset table
set table $s2 separator comma
plot 'scale_mpi.csv' using (column('ranks')):(column('measured_s')) with table
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'scale_mpi_ranks.png'
set title 'lightstage fit under MPI at 1024²: time against ranks (one core each)' font 'Sans,13'
set xlabel 'ranks'
set ylabel 'seconds'
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
plot $s0 using 1:2 with linespoints lt 1 title 'model: serial + parallel / n, floored by I/O', \
     $s1 using 1:2 with linespoints lt 2 title 'I/O floor (3 passes from one store as fast as this disk)', \
     $s2 using 1:2 with linespoints lt 3 title 'measured'

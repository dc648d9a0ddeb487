# scale_throughput.png from scale_medians.csv, written by lightstage. Re-plot in this folder: gnuplot scale_throughput.gp
set datafile separator comma
set table $s0 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'read (cache)')
unset table
set table $s1 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'read (disk)')
unset table
set table $s2 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'relight pass (cache)')
unset table
set table $s3 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'relight pass (disk)')
unset table
set table $s4 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'relight (disk)')
unset table
set table $s5 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'build')
unset table
set table $s6 separator comma
plot 'scale_medians.csv' using (column('megapixels')):(column('field_mib_per_s')) with table if (strcol('step') eq 'compress hsh3')
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'scale_throughput.png'
set title 'Field bytes through each step (relight: one image; pass: its reading and relighting)' font 'Sans,13'
set xlabel 'megapixels'
set ylabel 'field MiB/s'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.04, graph 0.06, graph 0.06
set logscale y
set ytics (20, 50, 100, 200, 500, 1000, 2000, 5000, 10000)
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
plot $s0 using 1:2 with linespoints lt 1 title 'read (cache)', \
     $s1 using 1:2 with linespoints lt 2 title 'read (disk)', \
     $s2 using 1:2 with linespoints lt 3 title 'relight pass (cache)', \
     $s3 using 1:2 with linespoints lt 4 title 'relight pass (disk)', \
     $s4 using 1:2 with linespoints lt 5 title 'relight (disk)', \
     $s5 using 1:2 with linespoints lt 6 title 'build', \
     $s6 using 1:2 with linespoints lt 7 title 'compress hsh3'

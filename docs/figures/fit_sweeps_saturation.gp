# fit_sweeps_saturation.png from fit_sweeps.csv, written by lightstage. Re-plot in this folder: gnuplot fit_sweeps_saturation.gp
set datafile separator comma
set table $s0 separator comma
plot 'fit_sweeps.csv' using (column('value')):(column('ls_mean_deg')) with table if (strcol('axis') eq 'saturation')
unset table
set table $s1 separator comma
plot 'fit_sweeps.csv' using (column('value')):(column('robust_mean_deg')) with table if (strcol('axis') eq 'saturation')
unset table
set table $s2 separator comma
plot 'fit_sweeps.csv' using (column('value')):(column('fit_mean_deg')):(strstrt(',27,28,29,30,31,', sprintf(',%d,', column(0))) == 0 ? '' : sprintf('%.0f%%', 100 * column('fit_flagged'))) with table if (strcol('axis') eq 'saturation')
unset table
set table $s3 separator comma
plot 'fit_sweeps.csv' using (column('value')):(column('fit_p95_deg')) with table if (strcol('axis') eq 'saturation')
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'fit_sweeps_saturation.png'
set title 'Normal error vs fraction of samples clipped (labels: fit, % flagged)' font 'Sans,13'
set xlabel 'fraction of samples clipped'
set ylabel 'angular error of the normal, deg'
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
plot $s0 using 1:2 with linespoints lt 1 title 'LS normals, mean', \
     $s1 using 1:2 with linespoints lt 2 title 'robust normals, mean', \
     $s2 using 1:2 with linespoints lt 3 title 'fit normals, mean', \
     $s2 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 3 notitle, \
     $s3 using 1:2 with linespoints lt 4 title 'fit normals, p95'

# fit_error_vs_throughput.png from fit.csv, written by lightstage. Re-plot in this folder: gnuplot fit_error_vs_throughput.gp
set datafile separator comma
set table $s0 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert [profiled]')
unset table
set table $s1 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Oren-Nayar [profiled]')
unset table
set table $s2 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert+TS [profiled]')
unset table
set table $s3 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert+Phong [profiled]')
unset table
set table $s4 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'BIC (L / ON / L+TS) [profiled]')
unset table
set table $s5 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert [LM]')
unset table
set table $s6 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Oren-Nayar [LM]')
unset table
set table $s7 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert+TS [LM]')
unset table
set table $s8 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'Lambert+Phong [LM]')
unset table
set table $s9 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')) with table if (strcol('method') eq 'BIC (L / ON / L+TS) [LM]')
unset table
set table $s10 separator comma
plot 'fit.csv' using (column('fit_pixels_per_s')):(column('relative_rmse')):(strstrt(',11,23,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('map')) with table if (strcol('method') eq 'basis materials')
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'fit_error_vs_throughput.png'
set title 'Model relighting error vs fit throughput (64x64 px, 150 LEDs)' font 'Sans,13'
set xlabel 'fit throughput, pixels/s (all cores)'
set ylabel 'relative RMSE vs ground truth'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.14, graph 0.06, graph 0.06
set logscale x
set xtics (1000, 2000, 5000, 10000, 20000, 50000, 100000, 200000, 500000)
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
plot $s0 using 1:2 with points lt 1 title 'Lambert [profiled]', \
     $s1 using 1:2 with points lt 2 title 'Oren-Nayar [profiled]', \
     $s2 using 1:2 with points lt 3 title 'Lambert+TS [profiled]', \
     $s3 using 1:2 with points lt 4 title 'Lambert+Phong [profiled]', \
     $s4 using 1:2 with points lt 5 title 'BIC (L / ON / L+TS) [profiled]', \
     $s5 using 1:2 with points lt 6 title 'Lambert [LM]', \
     $s6 using 1:2 with points lt 7 title 'Oren-Nayar [LM]', \
     $s7 using 1:2 with points lt 8 title 'Lambert+TS [LM]', \
     $s8 using 1:2 with points lt 9 title 'Lambert+Phong [LM]', \
     $s9 using 1:2 with points lt 10 title 'BIC (L / ON / L+TS) [LM]', \
     $s10 using 1:2 with points lt 11 title 'basis materials', \
     $s10 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 11 notitle

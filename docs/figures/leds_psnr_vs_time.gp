# leds_psnr_vs_time.png from leds.csv, written by lightstage. Re-plot in this folder: gnuplot leds_psnr_vs_time.gp
set datafile separator comma
set table $s0 separator comma
plot 'leds.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',0,9,18,27,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('leds')) with table if (strcol('map') eq 'sky_sun' && strcol('method') eq 'cells' && strcol('turns') eq '0')
unset table
set table $s1 separator comma
plot 'leds.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',1,10,19,28,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('leds')) with table if (strcol('map') eq 'sky_sun' && strcol('method') eq 'cells + sources' && strcol('turns') eq '0')
unset table
set table $s2 separator comma
plot 'leds.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',13,22,40,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('leds')) with table if (strcol('map') eq 'small_source' && strcol('method') eq 'cells' && strcol('turns') eq '0')
unset table
set table $s3 separator comma
plot 'leds.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',5,32,41,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('leds')) with table if (strcol('map') eq 'small_source' && strcol('method') eq 'cells + sources' && strcol('turns') eq '0')
unset table
set table $s4 separator comma
plot 'leds.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',8,17,26,35,44,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('leds')) with table if (strcol('map') eq 'softbox_studio' && strcol('method') eq 'cells' && strcol('turns') eq '0')
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'leds_psnr_vs_time.png'
set title 'Relighting from the field: PSNR vs time per frame (point labels: LEDs)' font 'Sans,13'
set xlabel 'relight time per frame, ms'
set ylabel 'PSNR vs ground truth, dB'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.14, graph 0.06, graph 0.06
set logscale x
set xtics (0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100)
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
plot $s0 using 1:2 with linespoints lt 1 title 'sky_sun', \
     $s0 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 1 notitle, \
     $s1 using 1:2 with linespoints lt 2 title 'sky_sun + sources', \
     $s1 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 2 notitle, \
     $s2 using 1:2 with linespoints lt 3 title 'small_source', \
     $s2 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 3 notitle, \
     $s3 using 1:2 with linespoints lt 4 title 'small_source + sources', \
     $s3 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 4 notitle, \
     $s4 using 1:2 with linespoints lt 5 title 'softbox_studio', \
     $s4 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 5 notitle

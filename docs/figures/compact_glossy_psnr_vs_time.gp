# compact_glossy_psnr_vs_time.png from compact.csv, written by lightstage. Re-plot in this folder: gnuplot compact_glossy_psnr_vs_time.gp
set datafile separator comma
set table $s0 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'raw' && strcol('scene') eq 'glossy')
unset table
set table $s1 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'pca global' && strcol('scene') eq 'glossy')
unset table
set table $s2 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',28,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'pca 16px tiles' && strcol('scene') eq 'glossy')
unset table
set table $s3 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'pca auto (noise floor)' && strcol('scene') eq 'glossy')
unset table
set table $s4 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',36,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'pca auto (held-out LEDs)' && strcol('scene') eq 'glossy')
unset table
set table $s5 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'ptm' && strcol('scene') eq 'glossy')
unset table
set table $s6 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',41,42,', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'hsh' && strcol('scene') eq 'glossy')
unset table
set table $s7 separator comma
plot 'compact.csv' using (column('relight_ms')):(column('psnr_db')):(strstrt(',', sprintf(',%d,', column(0))) == 0 ? '' : strcol('representation')) with table if (strcol('family') eq 'models' && strcol('scene') eq 'glossy')
unset table
set terminal pngcairo size 1000,700 noenhanced font 'Sans,11'
set output 'compact_glossy_psnr_vs_time.png'
set title 'Compact fields, glossy: held-out PSNR vs relight time per frame (labels: the front)' font 'Sans,13'
set xlabel 'relight time per frame (environment map), ms'
set ylabel 'PSNR on held-out LEDs, dB'
set format x '%g'
set format y '%g'
set grid xtics ytics mxtics mytics lc rgb '#dddddd'
set key below left Left reverse horizontal spacing 1.2 width 2 height 1
set autoscale fix
set offsets graph 0.04, graph 0.14, graph 0.06, graph 0.06
set logscale x
set xtics (0.02, 0.05, 0.1, 0.2, 0.5, 1, 2, 5)
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
plot $s0 using 1:2 with linespoints lt 1 title 'raw', \
     $s0 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 1 notitle, \
     $s1 using 1:2 with linespoints lt 2 title 'pca global', \
     $s1 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 2 notitle, \
     $s2 using 1:2 with linespoints lt 3 title 'pca 16px tiles', \
     $s2 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 3 notitle, \
     $s3 using 1:2 with linespoints lt 4 title 'pca auto (noise floor)', \
     $s3 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 4 notitle, \
     $s4 using 1:2 with linespoints lt 5 title 'pca auto (held-out LEDs)', \
     $s4 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 5 notitle, \
     $s5 using 1:2 with linespoints lt 6 title 'ptm', \
     $s5 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 6 notitle, \
     $s6 using 1:2 with linespoints lt 7 title 'hsh', \
     $s6 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 7 notitle, \
     $s7 using 1:2 with linespoints lt 8 title 'models', \
     $s7 using 1:2:3 with labels left offset char 0.8,0.5 font 'Sans,9' textcolor lt 8 notitle

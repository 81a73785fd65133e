# Shape error against time per edit, one labelled point per configuration of
# `sculpt-bench accuracy`. From the repository root:
#   build/bin/sculpt-bench accuracy --json --out-dat docs/accuracy.dat > docs/bench-accuracy.json
#   gnuplot docs/plot_accuracy.gp            # writes docs/accuracy.png
# Another table: gnuplot -e "dat='other.dat'; out='other.png'" docs/plot_accuracy.gp
#
# Columns of the .dat: 1 idx, 2 label, 3 group, 4 voxel_size, 5 ms_per_edit,
# 6 shape_error_mean, 7 shape_error_max, 8 volume_error_rel, 9 eikonal_mean_abs_error,
# 10 shape_error_edited_mean, 11 shape_error_edited_rms.

if (!exists("dat")) dat = "docs/accuracy.dat"
if (!exists("out")) out = "docs/accuracy.png"

set terminal pngcairo size 1800,640 font "DejaVu Sans,10" enhanced
set output out
set multiplot layout 1,3 title "sculpt-bench accuracy: fixed press scenario against the reference run (voxel 0.125, WENO5/RK3/Newton)"

set grid
set key top right
set format y "10^{%L}"
set xlabel "mean wall time per edit (ms)"
even(i) = int(i) % 2 == 0
grp(g) = strcol(3) eq g ? $10 : 1/0
grpv(g) = strcol(3) eq g ? $8 : 1/0

# (a) every configuration, log-log
set logscale xy
set title "(a) shape error near the strokes vs cost"
set ylabel "mean |{/Symbol f}_{test}| over reference vertices near the strokes (world units)"
plot dat using 5:(grp("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(grp("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(grp("voxel_size")) with points pt 9 ps 1.6 lc rgb "#d62728" title "voxel size", \
     dat using 5:(grp("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(grp("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:(even($1) ? $10 : 1/0):2 with labels offset char 0.8,0.5 left font ",8" notitle, \
     dat using 5:(even($1) ? 1/0 : $10):2 with labels offset char -0.8,-0.5 right font ",8" notitle

# (b) zoom: the configurations at the base voxel size with compensation on, linear axes
unset logscale
set format y "%.3f"
set title "(b) zoom: base voxel size, compensated"
set ylabel "mean |{/Symbol f}_{test}| near the strokes (world units)"
zoom(g) = (strcol(3) eq g && strcol(2) ne "no-comp" && strcol(2) ne "reinit-never" && $4 == base_voxel) ? $10 : 1/0
# the base voxel size is the default row's
stats dat using ((strcol(3) eq "default") ? $4 : 1/0) nooutput name "B"
base_voxel = B_max
plot dat using 5:(zoom("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(zoom("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(zoom("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(zoom("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:((strcol(2) ne "no-comp" && strcol(2) ne "reinit-never" && $4 == base_voxel && even($1)) ? $10 : 1/0):2 \
         with labels offset char 0.8,0.5 left font ",8" notitle, \
     dat using 5:((strcol(2) ne "no-comp" && strcol(2) ne "reinit-never" && $4 == base_voxel && !even($1)) ? $10 : 1/0):2 \
         with labels offset char -0.8,-0.5 right font ",8" notitle

# (c) volume error, log-log
set logscale xy
set format y "10^{%L}"
set title "(c) volume error vs cost"
set ylabel "|V_{final} - V_0| / V_0"
plot dat using 5:(grpv("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(grpv("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(grpv("voxel_size")) with points pt 9 ps 1.6 lc rgb "#d62728" title "voxel size", \
     dat using 5:(grpv("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(grpv("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:(even($1) ? $8 : 1/0):2 with labels offset char 0.8,0.5 left font ",8" notitle, \
     dat using 5:(even($1) ? 1/0 : $8):2 with labels offset char -0.8,-0.5 right font ",8" notitle

unset multiplot

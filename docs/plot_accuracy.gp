# Shape error against time per edit, one labelled point per configuration of
# `sculpt-bench accuracy`. From the repository root:
#   build/bin/sculpt-bench accuracy --json --out-dat docs/accuracy.dat > docs/bench-accuracy.json
#   gnuplot docs/plot_accuracy.gp            # writes docs/accuracy.png
# Another table: gnuplot -e "dat='other.dat'; out='other.png'" docs/plot_accuracy.gp
#
# Columns of the .dat: 1 idx, 2 label, 3 group, 4 voxel_size, 5 ms_per_edit,
# 6 shape_error_mean, 7 shape_error_max, 8 volume_error_rel, 9 eikonal_mean_abs_error,
# 10 shape_error_edited_mean, 11 shape_error_edited_rms.
#
# Most configurations sit at the base voxel size with Newton compensation and land within a
# few per cent of each other. Panels (a) and (c) leave that cluster unlabelled; panel (b)
# zooms into it with labels.

if (!exists("dat")) dat = "docs/accuracy.dat"
if (!exists("out")) out = "docs/accuracy.png"

set terminal pngcairo size 1800,700 font "DejaVu Sans,10" enhanced
set output out
set multiplot layout 1,3 title "sculpt-bench accuracy: fixed press scenario against the reference run (voxel 0.125, WENO5/RK3/Newton)"

# The base voxel size and time per edit are the default row's.
stats dat using ((strcol(3) eq "default") ? $4 : 1/0) nooutput name "B"
base_voxel = B_max
stats dat using ((strcol(3) eq "default") ? $5 : 1/0) nooutput name "T"
base_ms = T_max
stats dat using ((strcol(3) eq "default") ? $8 : 1/0) nooutput name "VE"
base_volerr = VE_max

even(i) = int(i) % 2 == 0
grp(g) = strcol(3) eq g ? $10 : 1/0
grpv(g) = strcol(3) eq g ? $8 : 1/0
# in the cluster: base voxel, compensated, reinitialised on every edit (shown in panel b).
# reinit-thr0.15 (the old threshold, reinitialises only some edits) lies well above the
# cluster, so it is labelled in (a) and left out of (b) to keep (b)'s scale tight.
zoomed(dummy) = strcol(2) ne "no-comp" && strcol(2) ne "reinit-never" && strcol(2) ne "reinit-thr0.15" && $4 == base_voxel
# label in (a) only what (b) does not show, or what is far from the default in time
lab_a(dummy) = !zoomed(0) || $5 > 2 * base_ms
# label in (c) only what differs from the default by more than 10x in volume error or 2x in time
lab_c(dummy) = $4 != base_voxel || $8 > 10 * base_volerr || $5 > 2 * base_ms
# label placement in (b), to keep labels of close points apart: 0 right-up, 1 left-down,
# 2 above, 3 below, 4 right-down, 5 left-up, 6 left. The default and reinit-every (same result
# as the default) get their own spots; two scheme rows are moved by name.
place(l, i) = l eq "default" ? 6 : l eq "reinit-every" ? 2 : \
              l eq "weno5-rk3" ? 4 : l eq "upwind-rk3" ? 5 : (even(i) ? 0 : 1)

set grid
set key top right
set xlabel "mean wall time per edit (ms)"

# (a) every configuration, log-log
set logscale xy
set format y "10^{%L}"
set title "(a) shape error near the strokes vs cost\n(unlabelled cluster: zoomed in (b))"
set ylabel "mean |{/Symbol f}_{test}| over reference vertices near the strokes (world units)"
plot dat using 5:(grp("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(grp("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(grp("voxel_size")) with points pt 9 ps 1.6 lc rgb "#d62728" title "voxel size", \
     dat using 5:(grp("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(grp("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:(lab_a(0) && even($1) ? $10 : 1/0):2 with labels offset char 0.8,0.5 left font ",9" notitle, \
     dat using 5:(lab_a(0) && !even($1) ? $10 : 1/0):2 with labels offset char -0.8,-0.5 right font ",9" notitle

# (b) zoom: the configurations at the base voxel size with compensation on; a log time axis
# spreads the 3-5 ms cluster
stats dat using (zoomed(0) ? $5 : 1/0) nooutput name "ZX"
set logscale x
unset logscale y
set xrange [ZX_min / 1.8 : ZX_max * 1.6]
set xtics add (2, 3, 4, 5, 7, 15, 20, 30, 50)
set autoscale yfix
set format y "%.4f"
set format x "%g"
set offsets 0, 0, graph 0.12, graph 0.12
set title "(b) zoom: base voxel size, compensated, reinitialised every edit\n(default and reinit-every coincide in error)"
set ylabel "mean |{/Symbol f}_{test}| near the strokes (world units)"
zoom(g) = (strcol(3) eq g && zoomed(0)) ? $10 : 1/0
zl(k) = (zoomed(0) && place(strcol(2), $1) == k) ? $10 : 1/0
plot dat using 5:(zoom("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(zoom("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(zoom("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(zoom("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:(zl(0)):2 with labels offset char 0.8,0.5 left font ",9" notitle, \
     dat using 5:(zl(1)):2 with labels offset char -0.8,-0.5 right font ",9" notitle, \
     dat using 5:(zl(2)):2 with labels offset char 0,1.5 center font ",9" notitle, \
     dat using 5:(zl(3)):2 with labels offset char 0,-1.5 center font ",9" notitle, \
     dat using 5:(zl(4)):2 with labels offset char 0.8,-0.5 left font ",9" notitle, \
     dat using 5:(zl(5)):2 with labels offset char -0.8,0.5 right font ",9" notitle, \
     dat using 5:(zl(6)):2 with labels offset char -1.2,0 right font ",9" notitle
set offsets 0, 0, 0, 0
set autoscale xy
set xtics autofreq

# (c) volume error, log-log
set logscale xy
set format x "%g"
set format y "10^{%L}"
set title "(c) volume error vs cost\n(unlabelled: base voxel size, Newton)"
set ylabel "|V_{final} - V_0| / V_0"
plot dat using 5:(grpv("default")) with points pt 7 ps 2.0 lc rgb "#000000" title "default", \
     dat using 5:(grpv("scheme")) with points pt 5 ps 1.3 lc rgb "#1f77b4" title "spatial x temporal", \
     dat using 5:(grpv("voxel_size")) with points pt 9 ps 1.6 lc rgb "#d62728" title "voxel size", \
     dat using 5:(grpv("reinit")) with points pt 11 ps 1.6 lc rgb "#2ca02c" title "reinit policy", \
     dat using 5:(grpv("compensation")) with points pt 13 ps 1.6 lc rgb "#9467bd" title "compensation", \
     dat using 5:(lab_c(0) && even($1) ? $8 : 1/0):2 with labels offset char 0.8,0.5 left font ",9" notitle, \
     dat using 5:(lab_c(0) && !even($1) ? $8 : 1/0):2 with labels offset char -0.8,-0.5 right font ",9" notitle

unset multiplot

# What accuracy costs for ball skins: points, contour bytes and build time against the chord
# tolerance (a fraction of the smallest radius), 200-ball chain of `sculpt-bench skin`.
# From the repository root:
#   build/bin/sculpt-bench skin --json --out-dat docs/skin_accuracy.dat > docs/bench-skin.json
#   gnuplot docs/plot_skin_accuracy.gp            # writes docs/skin_accuracy.png
#
# Columns of the .dat: 1 rel_tol, 2 tol, 3 points, 4 points_per_unit_length, 5 bytes,
# 6 bytes_per_point, 7 build_ms, 8 max_error_over_tol, 9 total_sections, 10 sections.

if (!exists("dat")) dat = "docs/skin_accuracy.dat"
if (!exists("out")) out = "docs/skin_accuracy.png"

set terminal pngcairo size 1200,500 font "DejaVu Sans,10" enhanced
set output out
set multiplot layout 1,2 title "sculpt-bench skin: chord tolerance vs cost (200 balls, hybrid)"

set logscale xy
set xrange [*:*] reverse
set grid
set key top left
set xlabel "chord tolerance / smallest radius"

set ylabel "count"
set title "(a) points and contour bytes"
plot dat using 1:3 with linespoints pt 7 title "points", \
     dat using 1:5 with linespoints pt 5 title "contour bytes (snapshot)"

set ylabel "ms"
set title "(b) build time (median of 5)"
plot dat using 1:7 with linespoints pt 7 title "Skin::Build"

unset multiplot

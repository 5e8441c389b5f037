# The plots of `voxtier bench`, drawn from results.csv. The bench embeds this file and writes it
# into its output folder as plots.gp, after these settings (gnuplot plots.gp there draws again):
#   scene     the scene of the sweeps and the scaling curves
#   modes     the bench's modes, e.g. "near_vulkan near_reference far hybrid"
#   families  the sweep families measured against the truth, each quoted: "'view set' 'sigma'"
#   variants  the snapshot scales of the error budget sweep, each quoted: "'x1' 'x3'"
#   plots     which plots to draw, of "speed_error motion_error frontier scaling_entities scaling_size"
# and the Pareto fronts of the speed/error plot (error, frame ms), which the report marks too, in
# pareto_mismatch.dat and pareto_displacement.dat; the speed–error frontier in frontier.dat (a
# block per variant of "speed-up PSNR budget") and its Pareto points in frontier_pareto.dat.

palette = "#1f77b4 #ff7f0e #2ca02c #d62728 #9467bd #8c564b #e377c2 #7f7f7f #bcbd22 #17becf #000000 #aec7e8"
mode_palette = "#1f77b4 #9467bd #ff7f0e #2ca02c #d62728 #8c564b"
# k: a position, given as a number or as a word of near_k / far_k below.
color(k) = word(palette, (int(0 + k) - 1) % words(palette) + 1)
mode_color(k) = word(mode_palette, (int(0 + k) - 1) % words(mode_palette) + 1)
mode(k) = word(modes, int(0 + k))
wants(plot) = strstrt(" ".plots." ", " ".plot." ") > 0
# The positions (in `modes`) of the modes that draw near sprites only, and of the all-far mode.
near_k = ""
far_k = ""
do for [k = 1:words(modes)] {
    if (strstrt(word(modes, k), "near_") == 1) { near_k = near_k." ".k }
    if (word(modes, k) eq "far") { far_k = far_k." ".k }
}
# results.csv rows are picked with `with table if (...)` into a datablock, one block (`index`) per
# series, so the lines of a series join its own points only.
read_csv = "set datafile separator comma; set datafile columnheaders"
read_blocks = "set datafile separator whitespace; set datafile nocolumnheaders"
end_block = "set print $rows append; print ''; print ''; unset print"

set terminal pngcairo size 1400,620 font ',10' noenhanced
set grid
set key outside right top

# Speed against error: the modes as single points, the sweep families as lines, the Pareto front.
if (wants("speed_error")) {
    @read_csv
    set print $rows
    unset print
    series = words(modes) + words(families)
    do for [k = 1:series] {
        set table $rows append
        if (k <= words(modes)) {
            plot 'results.csv' using (100 * column("mismatch_mean")):"far_displacement_worst_vpx":"frame_ms" with table \
                if (strcol("scene") eq scene && strcol("group") eq "modes" && strcol("mode") eq word(modes, k))
        } else {
            plot 'results.csv' using (100 * column("mismatch_mean")):"far_displacement_worst_vpx":"frame_ms" with table \
                if (strcol("scene") eq scene && strcol("group") eq "sweep" && column("has_error") == 1 && \
                    strcol("family") eq word(families, k - words(modes)))
        }
        unset table
        @end_block
    }
    @read_blocks
    label(k) = k <= words(modes) ? "mode ".word(modes, k) : word(families, k - words(modes))
    set terminal pngcairo size 1400,760 font ',10' noenhanced
    set output 'speed_error.png'
    set multiplot layout 1,2 title scene.": frame ms against error (each point: median frame ms, mean over path frames)"
    set logscale y
    set ylabel 'frame ms (log)'
    set key outside bottom center horizontal maxrows 3 font ',9'
    set title 'x: mean per-entity footprint mismatch (%)'
    plot for [k = 1:words(modes)] $rows index (k - 1) using 1:3 with points pt 5 + 2 * (k % 4) ps 2.2 lc rgb color(k) title label(k), \
         for [k = words(modes) + 1:series] $rows index (k - 1) using 1:3 with linespoints pt 5 + 2 * (k % 4) ps 1.1 lw 2 lc rgb color(k) title label(k), \
         'pareto_mismatch.dat' using 1:2 with steps lw 3 lc rgb '#555555' dt 2 title 'Pareto front', \
         '' using 1:2 with points pt 6 ps 2.6 lw 2 lc rgb '#000000' notitle
    set title 'x: worst silhouette displacement of a far entity drawn alone (virtual pixels)'
    plot for [k = 1:words(modes)] $rows index (k - 1) using 2:3 with points pt 5 + 2 * (k % 4) ps 2.2 lc rgb color(k) title label(k), \
         for [k = words(modes) + 1:series] $rows index (k - 1) using 2:3 with linespoints pt 5 + 2 * (k % 4) ps 1.1 lw 2 lc rgb color(k) title label(k), \
         'pareto_displacement.dat' using 1:2 with steps lw 3 lc rgb '#555555' dt 2 title 'Pareto front', \
         '' using 1:2 with points pt 6 ps 2.6 lw 2 lc rgb '#000000' notitle
    unset multiplot
    unset logscale
    unset title
    set terminal pngcairo size 1400,620 font ',10' noenhanced
    set key default
}

# In motion (issue 13): the in-motion frame ms against the in-motion min PSNR (vs all-near) and
# against the worst far displacement, the modes as points, the sweep families (error budget,
# ladder cap, ...) as lines.
if (wants("motion_error")) {
    @read_csv
    set print $rows
    unset print
    series = words(modes) + words(families)
    psnr(x) = x > 99 ? 99 : x
    do for [k = 1:series] {
        set table $rows append
        if (k <= words(modes)) {
            plot 'results.csv' using (psnr(column("in_motion_psnr_min"))):"far_displacement_worst_vpx":"in_motion_ms" with table \
                if (strcol("scene") eq scene && strcol("group") eq "modes" && strcol("mode") eq word(modes, k) && column("in_motion_ms") > 0)
        } else {
            plot 'results.csv' using (psnr(column("in_motion_psnr_min"))):"far_displacement_worst_vpx":"in_motion_ms" with table \
                if (strcol("scene") eq scene && strcol("group") eq "sweep" && column("has_error") == 1 && column("in_motion_ms") > 0 && \
                    strcol("family") eq word(families, k - words(modes)))
        }
        unset table
        @end_block
    }
    @read_blocks
    label(k) = k <= words(modes) ? "mode ".word(modes, k) : word(families, k - words(modes))
    set terminal pngcairo size 1400,760 font ',10' noenhanced
    set output 'motion_error.png'
    set multiplot layout 1,2 title scene.": in motion, frame ms against error (median frame ms of consecutive path frames after the cold start)"
    set logscale y
    set ylabel 'in-motion frame ms (log)'
    set key outside bottom center horizontal maxrows 3 font ',9'
    set title 'x: min frame PSNR against all-near in motion (dB, 99 = identical)'
    plot for [k = 1:words(modes)] $rows index (k - 1) using 1:3 with points pt 5 + 2 * (k % 4) ps 2.2 lc rgb color(k) title label(k), \
         for [k = words(modes) + 1:series] $rows index (k - 1) using 1:3 with linespoints pt 5 + 2 * (k % 4) ps 1.1 lw 2 lc rgb color(k) title label(k)
    set title 'x: worst silhouette displacement of a far entity drawn alone (virtual pixels)'
    plot for [k = 1:words(modes)] $rows index (k - 1) using 2:3 with points pt 5 + 2 * (k % 4) ps 2.2 lc rgb color(k) title label(k), \
         for [k = words(modes) + 1:series] $rows index (k - 1) using 2:3 with linespoints pt 5 + 2 * (k % 4) ps 1.1 lw 2 lc rgb color(k) title label(k)
    unset multiplot
    unset logscale
    unset title
    set terminal pngcairo size 1400,620 font ',10' noenhanced
    set key default
}

# The speed–error frontier: the error budget sweep in motion, one curve per snapshot scale, x the
# speed-up against the scene's fastest exact path, y the min PSNR; points labelled by budget.
if (wants("frontier")) {
    @read_blocks
    set output 'frontier.png'
    set title scene.": in motion, speed-up against error per snapshot scale (labels: error budget in virtual pixels)"
    set xlabel 'in-motion speed-up against the fastest exact path (near_reference or near_vulkan, median frame ms; log)'
    set ylabel 'min frame PSNR against all-near in motion (dB, 99 = identical)'
    set key outside right top
    # Speed-ups span from below 1 (a budget whose bakes cost more than they save) to tens.
    set logscale x 2
    set offsets graph 0.05, graph 0.05, graph 0.08, graph 0.05
    plot for [k = 1:words(variants)] 'frontier.dat' index (k - 1) using 1:2 with linespoints pt 7 ps 1.4 lw 2 lc rgb color(k) title word(variants, k), \
         for [k = 1:words(variants)] 'frontier.dat' index (k - 1) using 1:2:3 with labels offset char 0.6,char 0.7 left font ',9' tc rgb color(k) notitle, \
         'frontier_pareto.dat' using 1:2 with points pt 6 ps 2.6 lw 2 lc rgb '#000000' title 'Pareto frontier'
    set offsets
    unset logscale
    unset title
    unset xlabel
    unset ylabel
    set key default
}

# Scaling curves: one block per mode of (param, frame ms, near ms, near fragments, far blit ms,
# blit pixels, cold bake ms).
scaling_rows = 'using "param":"frame_ms":"near_ms":"near_fragments":"far_blit_ms":"blit_pixels":"cold_bake_ms" with table'
collect_scaling = "@read_csv; set print $rows; unset print; do for [k = 1:words(modes)] { set table $rows append; plot 'results.csv' @scaling_rows if (strcol('group') eq group && strcol('mode') eq word(modes, k)); unset table; @end_block }; @read_blocks"
frame_curves = "for [k = 1:words(modes)] $rows index (k - 1) using 1:2 with linespoints pt 7 lw 2 lc rgb mode_color(k) title word(modes, k).' frame'"

if (wants("scaling_entities")) {
    group = "scaling_entities"
    @collect_scaling
    set output 'scaling_entities.png'
    set multiplot layout 1,2 title scene.": frame ms against entity count, per mode (one frame, camera at t = 0)"
    set logscale x
    set logscale y
    set xlabel 'entities (log)'
    set ylabel 'ms (log)'
    set key inside left top font ',8' box opaque
    plot @frame_curves
    # Each tier's time against the work it does: shaded fragments (near), footprint pixels (far blit).
    set xlabel 'work per frame: shaded fragments (near) / footprint pixels (far blit)'
    set ylabel 'tier ms (log)'
    plot for [k in near_k] $rows index (k - 1) using 4:3 with linespoints pt 7 lw 2 lc rgb mode_color(k) title mode(k).': near ms vs shaded fragments', \
         for [k in far_k] $rows index (k - 1) using 6:5 with linespoints pt 5 lw 2 lc rgb mode_color(k) title 'far: blit ms vs footprint pixels'
    unset multiplot
    unset logscale
}

if (wants("scaling_size")) {
    group = "scaling_size"
    @collect_scaling
    set output 'scaling_size.png'
    set multiplot layout 1,2 title scene.": frame ms against model size, per mode (one frame, camera at t = 0)"
    set logscale x 2
    set logscale y
    set xlabel 'model side in voxels (side x side x side/2, same size in metres)'
    set ylabel 'ms (log)'
    set key inside left top font ',8' box opaque
    plot @frame_curves, \
         for [k in far_k] $rows index (k - 1) using 1:7 with linespoints pt 4 dt 2 lw 1.5 lc rgb mode_color(k) title 'far: cold bakes ms (once)'
    # Cost per unit of work: per shaded fragment (near), per footprint pixel (far blit).
    set ylabel 'ns per unit of work (log)'
    plot for [k in near_k] $rows index (k - 1) using 1:($3 * 1e6 / $4) with linespoints pt 7 lw 2 lc rgb mode_color(k) title mode(k).': ns per shaded fragment', \
         for [k in far_k] $rows index (k - 1) using 1:($5 * 1e6 / $6) with linespoints pt 5 lw 2 lc rgb mode_color(k) title 'far: ns per footprint pixel (blit)'
    unset multiplot
    unset logscale
}

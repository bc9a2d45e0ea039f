#!/bin/bash
# Run: tools/farm/split-bench.sh [PATHLIGHT]   (the built-in Cornell box, 512x512, 1024 spp; two rounds)
# 2 processes of 1 thread on sample ranges + merge, against one render of 2 threads.
B=${1:-target/release/pathlight}
B=$(realpath "$B"); D=$(mktemp -d); trap 'rm -rf "$D"' EXIT; cd "$D"
for round in 1 2; do
t0=$(date +%s.%N)
$B render --spp 1024 --threads 2 --out whole.exr --quiet 2>/dev/null
t1=$(date +%s.%N)
$B render --spp 1024 --threads 1 --samples 0..512 --out a.part --quiet 2>/dev/null &
$B render --spp 1024 --threads 1 --samples 512..1024 --out b.part --quiet 2>/dev/null &
wait
$B merge a.part b.part --out merged.exr 2>/dev/null
t2=$(date +%s.%N)
echo "round $round: one render 2 threads $(awk "BEGIN{print $t1-$t0}") s; 2 x 1 thread + merge $(awk "BEGIN{print $t2-$t1}") s"
done

#!/bin/sh
# Takes docs/images/tiled-screenshot/tiled-editor.png: the Tiled editor
# (Debian's tiled 1.8.2) showing levels/tiled_hall.tmx at 200 %, on a
# virtual 1280 x 800 screen. Needs the Debian packages tiled, xvfb,
# xdotool and imagemagick. Run from the repository's top folder.
set -eu
export DISPLAY=:97
Xvfb "$DISPLAY" -screen 0 1280x800x24 &
xvfb=$!
trap 'kill $xvfb' EXIT
sleep 2
tiled levels/tiled_hall.tmx &
tiled=$!
sleep 12
win=$(xdotool search --name tiled_hall | head -1)
xdotool windowsize "$win" 1280 800
sleep 1
# Close the Properties and Project panels, then zoom 157 % -> 300 % -> 200 %.
xdotool mousemove 750 600 click 1 key ctrl+equal sleep 1 key ctrl+equal sleep 1
xdotool mousemove 529 101 click 1 sleep 0.5 mousemove 252 32 click 1 sleep 1
xdotool mousemove 600 400 click 1 key ctrl+minus sleep 1
# The mouse off the map, so that no tile is highlighted.
xdotool mousemove 1100 620 sleep 1
import -window root docs/images/tiled-screenshot/tiled-editor.png
kill $tiled

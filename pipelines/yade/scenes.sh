#!/usr/bin/env bash
# Puts the Yade comparison's scenes into DIR (default out/bench/peers): the 500-particle scene
# and Yade's settled state of it, as kept here, and the 2000- and 5000-particle scenes made by
# make_scene.py (deterministic from --seed 1; python3 with numpy, which a virtual environment
# under out/ gets from PyPI when the system python has none). Files already there are kept.
# Usage: pipelines/yade/scenes.sh [DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
dir=${1:-out/bench/peers}
mkdir -p "$dir"
for f in scene_500.txt settled_500_state.txt run_yade.py; do
  [ -f "$dir/$f" ] || cp "$here/$f" "$dir/$f"
done
python=python3
if ! python3 -c 'import numpy' 2>/dev/null; then
  venv=${VENV:-out/venv}
  if [ ! -x "$venv/bin/python" ]; then
    echo "yade/scenes.sh: installing numpy into $venv (once)" >&2
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy
  fi
  python=$venv/bin/python
fi
for n in 2000 5000; do
  if [ ! -f "$dir/scene_$n.txt" ]; then
    echo "yade/scenes.sh: generating scene_$n.txt" >&2
    "$python" "$here/make_scene.py" --n "$n" --seed 1 > "$dir/scene_$n.txt.part"
    mv "$dir/scene_$n.txt.part" "$dir/scene_$n.txt"
  fi
done

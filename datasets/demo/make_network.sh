#!/usr/bin/env bash
# Regenerates kirchberg.net.xml from kirchberg.osm with SUMO's netconvert.
# The network is committed (so every machine gets the same one, whatever its
# SUMO version); this script documents exactly how it was made (SUMO 1.15).
set -euo pipefail
export SUMO_HOME=${SUMO_HOME:-/usr/share/sumo}
cd "$(dirname "$0")"
netconvert --osm-files kirchberg.osm \
  --type-files "$SUMO_HOME/data/typemap/osmNetconvert.typ.xml" \
  --geometry.remove --junctions.join --tls.guess-signals --output.street-names \
  --seed 42 -o kirchberg.net.xml

# End to end on the demo city: `raysweep run` on a short cut of the embedded
# demo (its OSM, SUMO network and settings: CFR stored, [ns3] table) writes
# ns3/table.h5; raysweep-ns3-cam simulates 802.11p over it for 1 s and every
# row of receptions.csv is one of its counted receptions. Options as "--name value"
# here (ns-3 itself spells them "--name=value"; the examples take both).
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
file(WRITE ${WORK}/city.toml
"[city]
name = \"demo-cut\"
osm = \"${DEMO}/kirchberg.osm\"
net = \"${DEMO}/kirchberg.net.xml\"
[scene]
clip_distance_m = 150
[traffic]
seed = 42
end_s = 40
period_s = 1.5
classes = { passenger = 8, truck = 1, bus = 1 }
[sweep]
begin_s = 38
end_s = 39.95
cfr = \"80211p\"
[radio]
antenna = \"dipole\"
[tracer]
rays_per_source = 1024
[ns3]
subcarriers_per_band = 4
")
execute_process(COMMAND ${RAYSWEEP} run ${WORK}/city.toml --out ${WORK}/out RESULT_VARIABLE rc OUTPUT_VARIABLE log
                ERROR_VARIABLE log)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "raysweep run failed (${rc}): ${log}")
endif()
execute_process(COMMAND ${RAYSWEEP} validate ${WORK}/out/ns3/table.h5 RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "raysweep validate failed on the demo table (${rc})")
endif()
execute_process(COMMAND ${CAM} --table ${WORK}/out/ns3/table.h5 --out ${WORK}/cam --duration 1 --seed=2
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "raysweep-ns3-cam failed on the demo table (${rc}): ${err}")
endif()
file(STRINGS ${WORK}/cam/receptions.csv lines)
list(LENGTH lines n)
math(EXPR rows "${n} - 1")
file(READ ${WORK}/cam/summary.json summary)
string(JSON receptions GET "${summary}" receptions)
string(JSON received GET "${summary}" received)
if(NOT rows EQUAL receptions OR receptions LESS 10 OR received LESS 1 OR received GREATER receptions)
  message(FATAL_ERROR "demo table: rows ${rows}, receptions ${receptions}, received ${received}")
endif()
message(STATUS "ns-3 on the demo table: ${receptions} receptions, ${received} decoded")

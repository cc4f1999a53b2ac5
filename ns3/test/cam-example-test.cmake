# End-to-end run of raysweep-ns3-cam on the synthetic table of raysweep-ns3-test
# (4 vehicles, 1 s): the table validates, the example writes receptions.csv with
# the documented header and summary.json with decoded receptions.
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})
execute_process(COMMAND ${TEST_BIN} --write-table ${WORK}/table.h5 RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "writing the table failed (${rc})")
endif()
execute_process(COMMAND ${RAYSWEEP} validate ${WORK}/table.h5 RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "raysweep validate failed on the table (${rc})")
endif()
execute_process(COMMAND ${CAM} --table=${WORK}/table.h5 --out=${WORK}/out --duration=0.8 --rate-hz=10 --seed=3
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "raysweep-ns3-cam failed (${rc})")
endif()
file(STRINGS ${WORK}/out/receptions.csv lines)
list(GET lines 0 header)
if(NOT header STREQUAL "time_s,tx,rx,tx_power_dbm,rx_power_dbm,los_class,received,distance_m")
  message(FATAL_ERROR "unexpected header: ${header}")
endif()
list(LENGTH lines n)
file(READ ${WORK}/out/summary.json summary)
string(JSON receptions GET "${summary}" receptions)
string(JSON received GET "${summary}" received)
math(EXPR rows "${n} - 1")
if(NOT rows EQUAL receptions OR receptions LESS 20 OR NOT received EQUAL receptions)
  # Gains of -60 .. -100 dB at 23 dBm and 6 Mb/s: every reception decodes
  # (strong, no hidden terminals on 4 nodes in reach of each other).
  message(FATAL_ERROR "rows ${rows}, receptions ${receptions}, received ${received}")
endif()
# Out of the table: a usage error naming the table, exit status 2.
execute_process(COMMAND ${CAM} --table=${WORK}/table.h5 --out=${WORK}/out2 --start=50 RESULT_VARIABLE rc
                ERROR_VARIABLE err)
if(NOT rc EQUAL 2 OR NOT err MATCHES "table.h5")
  message(FATAL_ERROR "--start outside the table: exit ${rc}, ${err}")
endif()
message(STATUS "ns-3 example: ${receptions} receptions, all decoded")

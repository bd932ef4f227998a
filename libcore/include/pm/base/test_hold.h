#pragma once
// A test-only way to stop a run at a named point, so that a test can signal it
// at a moment it has observed instead of after a guessed delay (issue #23).
//
// With PM_TEST_HOLD=<point> in the environment, the run that reaches <point>
// prints one line "<tool>: test hold at <point>" on stderr (whatever the
// verbosity) and then waits, doing nothing, until a signal ends it. After
// PM_TEST_HOLD_SECONDS (default 120) it gives up with an error, so a test that
// forgets to signal cannot hang. Without the variable, hold points cost one
// comparison and do nothing.
//
// Points:
//   stage:<name>  at the start of every ScopedStage <name> (e.g. stage:flow)
//   commit        after the tool's body, when every output is written as a
//                 temporary file and none is renamed into place yet
#include <string>

namespace pm {

/// Hold here if PM_TEST_HOLD names `point`. \throw Error when the hold times out.
void test_hold_point(const std::string& point);

}  // namespace pm

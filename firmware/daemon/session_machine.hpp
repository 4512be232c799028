// The kiosk session as an explicit state machine: a pure transition function (state, input) ->
// (next state, action). The daemon performs the actions (enrol, record, process, export) and
// feeds their outcomes back as inputs, so every path, including cancel and retry, is testable
// without a camera.
//
//   idle --start--> enrolled --enrolled--> guide(i) --press--> recording --take_done-->
//   processing --qa_passed--> guide(i+1) ... --qa_passed(last)--> complete
//   processing --qa_failed--> retry --press--> recording
//   any session state --cancel--> idle (the session stays incomplete and can be resumed)
//   idle --resume--> guide(next capture);  idle <--mode--> tracking;  any --failed--> error
#pragma once

#include <optional>

#include "drivers/gpio/gpio.hpp"

namespace fb {

enum class KioskState {
  kIdle,        // ready for a new subject
  kEnrolled,    // subject and session created, about to show the first guide
  kGuide,       // showing guide expression i, waiting for the subject (button or page)
  kRecording,   // recording the head-turn take and fusing it frame by frame
  kProcessing,  // fused depth, landmarks, quick fit, quality check
  kRetry,       // the take failed the quality check; waiting to record it again
  kComplete,    // all captures done; the session is ready for the host
  kTracking,    // tracking mode: streaming head pose and weights
  kError,       // the camera or the store failed; press to go back to idle
};

enum class KioskInput {
  kStart,     // main button / page: new subject
  kPress,     // main button / page "I'm ready" or "retry"
  kCancel,    // long press on main / page cancel
  kMode,      // mode button / page: toggle tracking
  kResume,    // page: continue an incomplete session
  kEnrolled,  // the daemon created subject + session
  kTakeDone,  // the take is recorded and fused
  kQaPassed,  // committed; more captures to go
  kLastDone,  // committed; that was the last capture
  kQaFailed,  // rejected by the quality check
  kFailed,    // an operation failed
};

enum class KioskAction {
  kNone,
  kEnroll,     // create subject + session
  kShowGuide,  // present the next capture's guide
  kRecord,     // record + fuse the current capture
  kProcess,    // landmarks, fit, QA, commit or reject
  kAbandon,    // stop whatever runs; the current capture stays not done
  kFinish,     // export the complete session
  kStartTracking,
  kStopTracking,
  kResumeSession,  // find the session's next capture and show its guide
};

struct KioskTransition {
  KioskState next;
  KioskAction action;
};

// nullopt = the input means nothing in this state (ignored, e.g. a press while processing).
std::optional<KioskTransition> kiosk_transition(KioskState state, KioskInput input);

// Which LED pattern a state shows.
LedPattern led_for(KioskState state);
// Maps a button press to a machine input.
KioskInput input_for(const ButtonEvent& event, KioskState state);

const char* to_string(KioskState state);
const char* to_string(KioskInput input);
bool in_session(KioskState state);

}  // namespace fb

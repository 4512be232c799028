#include "firmware/daemon/session_machine.hpp"

namespace fb {

bool in_session(KioskState s) {
  return s == KioskState::kEnrolled || s == KioskState::kGuide || s == KioskState::kRecording ||
         s == KioskState::kProcessing || s == KioskState::kRetry;
}

std::optional<KioskTransition> kiosk_transition(KioskState s, KioskInput in) {
  using S = KioskState;
  using I = KioskInput;
  using A = KioskAction;
  if (in == I::kFailed) return KioskTransition{S::kError, A::kAbandon};
  if (in == I::kCancel && in_session(s)) return KioskTransition{S::kIdle, A::kAbandon};
  switch (s) {
    case S::kIdle:
      if (in == I::kStart || in == I::kPress) return KioskTransition{S::kEnrolled, A::kEnroll};
      if (in == I::kResume) return KioskTransition{S::kGuide, A::kResumeSession};
      if (in == I::kMode) return KioskTransition{S::kTracking, A::kStartTracking};
      break;
    case S::kEnrolled:
      if (in == I::kEnrolled) return KioskTransition{S::kGuide, A::kShowGuide};
      break;
    case S::kGuide:
      if (in == I::kPress) return KioskTransition{S::kRecording, A::kRecord};
      break;
    case S::kRecording:
      if (in == I::kTakeDone) return KioskTransition{S::kProcessing, A::kProcess};
      break;
    case S::kProcessing:
      if (in == I::kQaPassed) return KioskTransition{S::kGuide, A::kShowGuide};
      if (in == I::kLastDone) return KioskTransition{S::kComplete, A::kFinish};
      if (in == I::kQaFailed) return KioskTransition{S::kRetry, A::kNone};
      break;
    case S::kRetry:
      if (in == I::kPress) return KioskTransition{S::kRecording, A::kRecord};
      // The operator corrected the landmarks of the rejected take and the refit passed.
      if (in == I::kQaPassed) return KioskTransition{S::kGuide, A::kShowGuide};
      if (in == I::kLastDone) return KioskTransition{S::kComplete, A::kFinish};
      break;
    case S::kComplete:
      if (in == I::kStart || in == I::kPress) return KioskTransition{S::kEnrolled, A::kEnroll};
      if (in == I::kCancel) return KioskTransition{S::kIdle, A::kNone};
      if (in == I::kMode) return KioskTransition{S::kTracking, A::kStartTracking};
      break;
    case S::kTracking:
      if (in == I::kMode || in == I::kCancel) return KioskTransition{S::kIdle, A::kStopTracking};
      break;
    case S::kError:
      if (in == I::kPress || in == I::kCancel || in == I::kStart)
        return KioskTransition{S::kIdle, A::kNone};
      break;
  }
  return std::nullopt;
}

LedPattern led_for(KioskState s) {
  switch (s) {
    case KioskState::kRecording:
    case KioskState::kTracking:
      return LedPattern::kRecording;
    case KioskState::kProcessing:
    case KioskState::kEnrolled:
      return LedPattern::kProcessing;
    case KioskState::kRetry:
    case KioskState::kError:
      return LedPattern::kError;
    default:
      return LedPattern::kReady;
  }
}

KioskInput input_for(const ButtonEvent& e, KioskState) {
  if (e.button == ButtonId::kMode) return KioskInput::kMode;
  return e.kind == PressKind::kLong ? KioskInput::kCancel : KioskInput::kPress;
}

const char* to_string(KioskState s) {
  switch (s) {
    case KioskState::kIdle:
      return "idle";
    case KioskState::kEnrolled:
      return "enrolled";
    case KioskState::kGuide:
      return "guide";
    case KioskState::kRecording:
      return "recording";
    case KioskState::kProcessing:
      return "processing";
    case KioskState::kRetry:
      return "retry";
    case KioskState::kComplete:
      return "complete";
    case KioskState::kTracking:
      return "tracking";
    case KioskState::kError:
      return "error";
  }
  return "?";
}

const char* to_string(KioskInput i) {
  switch (i) {
    case KioskInput::kStart:
      return "start";
    case KioskInput::kPress:
      return "press";
    case KioskInput::kCancel:
      return "cancel";
    case KioskInput::kMode:
      return "mode";
    case KioskInput::kResume:
      return "resume";
    case KioskInput::kEnrolled:
      return "enrolled";
    case KioskInput::kTakeDone:
      return "take_done";
    case KioskInput::kQaPassed:
      return "qa_passed";
    case KioskInput::kLastDone:
      return "last_done";
    case KioskInput::kQaFailed:
      return "qa_failed";
    case KioskInput::kFailed:
      return "failed";
  }
  return "?";
}

}  // namespace fb

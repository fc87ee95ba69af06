// Channel names of the placerec LCM protocol (DESIGN.md "LCM protocol"), shared by the server and
// client adapters so that both spell them alike.
#pragma once

#include <cstddef>
#include <string>

namespace placerec {

// Frames from robots (frame_t).
inline constexpr char kFrameChannel[] = "PLACEREC_FRAME";
// Answers (result_t) go to kResultChannelPrefix + robot id.
inline constexpr char kResultChannelPrefix[] = "PLACEREC_RESULT_";
// Answers to frames whose robot id cannot name a channel (result_t).
inline constexpr char kInvalidRobotResultChannel[] = "PLACEREC_RESULT";
// The server's heartbeat (status_t), once a second.
inline constexpr char kStatusChannel[] = "PLACEREC_STATUS";
// Scene-change alarms for operators (change_t, protocol 5), one per change at a known place.
inline constexpr char kChangeChannel[] = "PLACEREC_CHANGE";

// LCM limits channel names to 63 bytes (LCM_MAX_CHANNEL_NAME_LENGTH), so a robot id that names
// its answer channel has at most 63 - 16 = 47 bytes.
inline constexpr size_t kMaxLcmChannelLength = 63;
inline constexpr size_t kMaxWireRobotIdLength =
    kMaxLcmChannelLength - (sizeof(kResultChannelPrefix) - 1);

// Whether `robot` can name its answer channel and is a robot id the map accepts: 1 to
// kMaxWireRobotIdLength bytes, each an ASCII letter, digit, '_', '-' or '.', so that every LCM
// binding (C, C++, Python, Java, Lua, Go; they subscribe by regular expression and some decode
// channel names as UTF-8) can subscribe to the answer channel. On false, *why says what is wrong
// (for the error answer).
inline bool IsValidWireRobotId(const std::string& robot, std::string* why) {
  if (robot.empty()) {
    *why = "robot id is empty";
    return false;
  }
  if (robot.size() > kMaxWireRobotIdLength) {
    *why = "robot id is " + std::to_string(robot.size()) + " bytes; the limit is " +
           std::to_string(kMaxWireRobotIdLength) + " (answers go to channel " +
           kResultChannelPrefix + "<robot>, and LCM channel names have at most " +
           std::to_string(kMaxLcmChannelLength) + " bytes)";
    return false;
  }
  for (size_t i = 0; i < robot.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(robot[i]);
    if (c < 0x20 || c == 0x7f) {
      *why = "robot id contains a control character";
      return false;
    }
    const bool allowed = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                         (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
    if (!allowed) {
      static const char kHex[] = "0123456789abcdef";
      *why = std::string("robot id byte ") + std::to_string(i) + " (0x" + kHex[c >> 4] +
             kHex[c & 15] +
             ") is not allowed: use ASCII letters, digits, '_', '-' and '.' only, so that every "
             "LCM binding can subscribe to the answer channel " +
             kResultChannelPrefix + "<robot>";
      return false;
    }
  }
  return true;
}

// The channel the answer to a frame of `robot` goes to: the robot's own channel, or
// kInvalidRobotResultChannel when the id cannot name one.
inline std::string ResultChannel(const std::string& robot) {
  std::string why;
  return IsValidWireRobotId(robot, &why) ? kResultChannelPrefix + robot
                                         : std::string(kInvalidRobotResultChannel);
}

}  // namespace placerec

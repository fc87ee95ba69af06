// Decoding a received LCM message without trusting it.
#pragma once

#include <cstddef>
#include <exception>

namespace placerec {

// Decodes `size` bytes into `message` (an lcm-gen type); false when they are not one. lcm-gen's
// decoders size their arrays from the counts they read before checking the bytes are there, so a
// forged count (e.g. -1) makes them throw: that is a bad message too, never an exception on a
// receive thread. (The server checks frame_t's counts before decoding: server/protocol.cc.)
template <typename Message>
bool DecodeLcmMessage(const void* data, size_t size, Message* message) {
  try {
    return message->decode(data, 0, static_cast<int>(size)) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace placerec

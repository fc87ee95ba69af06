// Decoding a received LCM message without trusting it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <exception>

#include "proto/wire_lengths.h"

namespace placerec {

// Decodes `size` bytes into `message` (an lcm-gen type with a wire::LengthsFit walk); false when
// they are not one. lcm-gen's decoders size their arrays from the counts they read before checking
// the bytes are there, so every count is checked first (a forged one made a receiver allocate
// gigabytes), and an exception of the decoder is a bad message too, never one on a receive
// thread. (The server checks frame_t's counts before decoding: server/protocol.cc.)
template <typename Message>
bool DecodeLcmMessage(const void* data, size_t size, Message* message) {
  if (data == nullptr || size < 8 || size > static_cast<size_t>(INT32_MAX) ||
      !wire::LengthsFit(data, size, message)) {
    return false;
  }
  try {
    return message->decode(data, 0, static_cast<int>(size)) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace placerec

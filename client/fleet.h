// A fleet simulation (issue 24 item 5): N robots replay a run against a placerec-server at a fixed
// frame rate each, open loop (a robot's camera does not wait for answers), with offset starts so
// that they are at different places of the route. Measures what a site operator sizes a server
// by: answers per second, latency percentiles, "overloaded" answers and timeouts.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/client.h"
#include "common/eval/run.h"
#include "common/util/status.h"

namespace placerec {

struct FleetOptions {
  int robots = 4;                      // simulated robots, ids fleet000, fleet001, ...
  double rate_hz = 1.0;                // frames per second per robot
  double duration_s = 60;              // sending time; answers are awaited after it
  double query_share = 0.0;            // share of frames sent query-only (the rest are inserted)
  std::string robot_prefix = "fleet";  // with the robot's number, a valid robot id
  double timeout_s = 60;               // per frame, from its publication
  bool progress = true;                // a progress line on stderr
  // When set (Ctrl-C): no further frame is sent, the frames sent are awaited, and the report
  // covers them ("interrupted" in fleet.json).
  const std::atomic<bool>* stop = nullptr;

  bool Check(std::string* error) const;
};

// Frames one robot may be asked to send (--duration times --rate).
constexpr double kMaxFleetFramesPerRobot = 1e7;

// Robot `robot`'s id: the prefix and the number, at least three digits (fleet007).
std::string FleetRobotId(const std::string& prefix, int robot);

struct FleetReport {
  int frames = 0;  // published
  std::vector<FrameResult> results;
  nlohmann::json summary;  // what fleet.json holds
};

// Replays `run`'s frames (all robots of the run, in frame order) as options.robots robots; robot
// i starts i/robots of the way along the run and wraps around. An error only for bad options or
// an unreadable image.
StatusOr<FleetReport> RunFleet(PlacerecClient* client, const Run& run, const FleetOptions& options);

}  // namespace placerec

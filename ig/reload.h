// Config reload (SIGHUP): which changed keys can take effect between two frames and which need
// a restart. A reload never half-applies: the new files are parsed and validated completely
// first (a bad file leaves the running config untouched), then every changed reloadable key is
// taken and every other changed key is reported and keeps its running value.
#pragma once

#include <string>
#include <vector>

#include "ig/config.h"

namespace ig {

struct ReloadPlan {
  std::vector<std::string> applied;      // reloadable keys whose value changed, e.g. "scene.fog.visibility_m"
  std::vector<std::string> needRestart;  // other keys whose value changed (running value kept)
};

// `merged*` = the running configs with every changed reloadable key taken from the new ones.
// `snapshotsAvailable`: snapshots were on at start-up (the snapshot folder was made then), so a
// reload may switch them on again after an earlier reload switched them off. The overload
// without it takes that from `runC`.
ReloadPlan planReload(const ServiceConfig& runC, const SceneConfig& runS, const ServiceConfig& newC,
                      const SceneConfig& newS, ServiceConfig& mergedC, SceneConfig& mergedS, bool snapshotsAvailable);
ReloadPlan planReload(const ServiceConfig& runC, const SceneConfig& runS, const ServiceConfig& newC,
                      const SceneConfig& newS, ServiceConfig& mergedC, SceneConfig& mergedS);

// "a, b, c" (or "none").
std::string joinKeys(const std::vector<std::string>& keys);

}  // namespace ig

#include "lightstage/backend_registry.h"

#include <gtest/gtest.h>

#include "lightstage/errors.h"

namespace ls {
namespace {

Backend named(const std::string& name, std::string description = "") {
  Backend b;
  b.name = name;
  b.description = std::move(description);
  b.open = [](const BackendRequest&) { return OpenedBackend{}; };
  return b;
}

TEST(BackendRegistry, FindsRegisteredBackendsByName) {
  BackendRegistry registry;
  registry.add(named("sim"));
  registry.add(named("aravis"));
  EXPECT_EQ(registry.find("aravis", "stage.json").name, "aravis");
  EXPECT_TRUE(registry.contains("sim"));
  EXPECT_FALSE(registry.contains("v4l2"));
  EXPECT_EQ(registry.names(), (std::vector<std::string>{"sim", "aravis"}));
}

TEST(BackendRegistry, UnknownBackendNamesTheStageFileFieldAndTheChoices) {
  BackendRegistry registry;
  registry.add(named("sim"));
  registry.add(named("aravis"));
  try {
    (void)registry.find("gige", "lab_dome.json");
    FAIL() << "an unknown back-end was found";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("lab_dome.json: camera.backend"), std::string::npos) << what;
    EXPECT_NE(what.find("\"sim\", \"aravis\""), std::string::npos) << what;
    EXPECT_NE(what.find("got \"gige\""), std::string::npos) << what;
  }
}

TEST(BackendRegistry, RegisteringANameAgainReplacesIt) {
  BackendRegistry registry;
  registry.add(named("sim", "first"));
  registry.add(named("sim", "second"));
  EXPECT_EQ(registry.names().size(), 1u);
  EXPECT_EQ(registry.find("sim", "s.json").description, "second");
}

}  // namespace
}  // namespace ls

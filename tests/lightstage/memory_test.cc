// The memory budget: sizes with units, the refusals of what is not one (naming the option and
// the text), the one default, and the --memory option every command binds.
#include "lightstage/memory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/memory_option.h"

namespace ls {
namespace {

using ::testing::HasSubstr;

constexpr std::size_t kKiB = 1024, kMiB = kKiB << 10, kGiB = kMiB << 10;

std::string refusal(const std::string& text, const std::string& option = "--memory") {
  try {
    (void)MemoryBudget::parse(text, option);
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(MemoryBudget, ParsesBytesAndUnitsAsPowersOf1024) {
  EXPECT_EQ(MemoryBudget::parse("33554432").bytes(), 32 * kMiB);
  EXPECT_EQ(MemoryBudget::parse("512M").bytes(), 512 * kMiB);
  EXPECT_EQ(MemoryBudget::parse("2G").bytes(), 2 * kGiB);
  EXPECT_EQ(MemoryBudget::parse("2g").bytes(), 2 * kGiB);
  EXPECT_EQ(MemoryBudget::parse("1.5GiB").bytes(), 3 * kGiB / 2);
  EXPECT_EQ(MemoryBudget::parse("64MiB").bytes(), 64 * kMiB);
  EXPECT_EQ(MemoryBudget::parse("64MB").bytes(), 64 * kMiB);
  EXPECT_EQ(MemoryBudget::parse("16K").bytes(), 16 * kKiB);
  EXPECT_EQ(MemoryBudget::parse("1T").bytes(), kGiB << 10);
  EXPECT_EQ(MemoryBudget::parse(" 256 M ").bytes(), 256 * kMiB);
  EXPECT_EQ(MemoryBudget::parse("100000B").bytes(), 100000u);
  EXPECT_EQ(MemoryBudget::parse("18446744073709551615").bytes(), ~std::size_t(0));
  EXPECT_TRUE(MemoryBudget::parse("2G").given());
}

TEST(MemoryBudget, RefusesWhatIsNotASizeNamingTheOptionAndTheText) {
  EXPECT_THAT(refusal("-1"), HasSubstr("--memory '-1': a size cannot be negative"));
  EXPECT_THAT(refusal("-5"), HasSubstr("--memory '-5': a size cannot be negative"));
  EXPECT_THAT(refusal("-2G"), HasSubstr("cannot be negative"));
  EXPECT_THAT(refusal("18446744073709551616"),
              HasSubstr("--memory '18446744073709551616': too large"));
  EXPECT_THAT(refusal("20000000T"), HasSubstr("too large"));
  EXPECT_THAT(refusal("0"), HasSubstr("--memory '0': must be more than 0"));
  EXPECT_THAT(refusal("0G"), HasSubstr("must be more than 0"));
  EXPECT_THAT(refusal("1"), HasSubstr("--memory '1': below 16 KiB"));
  EXPECT_THAT(refusal("16383"), HasSubstr("below 16 KiB"));
  EXPECT_THAT(refusal("lots"), HasSubstr("--memory 'lots': not a size"));
  EXPECT_THAT(refusal("lots"), HasSubstr("e.g. 512M, 2G"));
  for (const std::string bad : {"", "M", "2X", "2 GB B", "1.2.3G", ".5G", "5.G", "1e9", "0x100",
                                "nan", "inf", "2Gi", "+", "2,5G"}) {
    EXPECT_THAT(refusal(bad), HasSubstr("not a size")) << "'" << bad << "'";
  }
  EXPECT_THAT(refusal("1000.5"), HasSubstr("a number of bytes must be whole"));
  EXPECT_THAT(refusal("x", "--budget"), HasSubstr("--budget 'x'"));
}

TEST(MemoryBudget, UnsetIsHalfOfTheMemoryAvailable) {
  const MemoryBudget unset;
  EXPECT_FALSE(unset.given());
  EXPECT_EQ(unset.given_bytes(), 0u);
  // Within what the system reports between the two reads.
  const double half = double(available_memory_bytes()) / 2;
  EXPECT_NEAR(double(unset.bytes()), half, 0.1 * half);
  EXPECT_EQ(unset.to_string(), "half of the memory available");
  EXPECT_EQ(MemoryBudget(0), unset);  // 0, as options files record it, is unset.
  // Unset, an image set's budget is kImageSetBytes (or the default, when that is less).
  EXPECT_EQ(unset.bytes_or(MemoryBudget::kImageSetBytes),
            std::min(MemoryBudget::kImageSetBytes, MemoryBudget::default_bytes()));
  EXPECT_EQ(MemoryBudget(kGiB).bytes_or(MemoryBudget::kImageSetBytes), kGiB);
  EXPECT_EQ(MemoryBudget(kGiB).to_string(), "1 GiB");
  EXPECT_EQ(MemoryBudget(3 * kGiB / 2).to_string(), "1.5 GiB");
  EXPECT_EQ(format_bytes(20000), "19.5 KiB");
  EXPECT_EQ(format_bytes(1000), "1000 bytes");
}

TEST(MemoryBudget, ASmallBudgetIsTakenWithANote) {
  EXPECT_THAT(MemoryBudget::parse("20000").note(), HasSubstr("--memory 19.5 KiB is below 16 MiB"));
  EXPECT_THAT(MemoryBudget::parse("20000").note(), HasSubstr("taken as given"));
  EXPECT_EQ(MemoryBudget::parse("16M").note(), "");
  // More than the machine has: said, with what is available and what is used.
  EXPECT_THAT(MemoryBudget::parse("100000T").note(), HasSubstr("--memory 97.7 PiB is more than"));
  EXPECT_THAT(MemoryBudget::parse("100000T").note(),
              HasSubstr("of memory available: used as given"));
  EXPECT_EQ(MemoryBudget().note(), "");
}

// The option as a command binds it: negative values reach the parser (not taken for an option),
// refusals leave CLI11 as InputError, the help states the meaning, units and default.
TEST(MemoryBudget, OptionBindsEveryFormAndRefusesBadValues) {
  const auto parse = [](std::vector<std::string> args, MemoryBudget& budget) {
    CLI::App app{"test"};
    add_memory_option(app, budget, "Test: what it bounds.");
    std::reverse(args.begin(), args.end());
    app.parse(args);
    return app.help();
  };
  MemoryBudget budget;
  const std::string help = parse({}, budget);
  EXPECT_FALSE(budget.given());
  EXPECT_THAT(help, HasSubstr("--memory SIZE"));
  EXPECT_THAT(help, HasSubstr("Test: what it bounds."));
  EXPECT_THAT(help, HasSubstr("powers of 1024"));
  EXPECT_THAT(help, HasSubstr("Default: half of the memory available."));
  (void)parse({"--memory", "2G"}, budget);
  EXPECT_EQ(budget.bytes(), 2 * kGiB);
  (void)parse({"--memory=512M"}, budget);
  EXPECT_EQ(budget.bytes(), 512 * kMiB);
  for (const std::string bad : {"-1", "-5", "0", "1", "18446744073709551616", "big"}) {
    MemoryBudget refused;
    try {
      (void)parse({"--memory", bad}, refused);
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("--memory '" + bad + "'"));
    }
  }
  MemoryBudget bench(64 * kMiB);  // A command with its own default says it.
  CLI::App app{"bench"};
  add_memory_option(app, bench, "Bench.");
  EXPECT_THAT(app.help(), HasSubstr("Default: 64 MiB."));
}

}  // namespace
}  // namespace ls

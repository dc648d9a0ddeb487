#pragma once
// The --memory option of every command (the app's and the viewer's CLI11 commands): one binding,
// one parser (MemoryBudget::parse), one help. Header-only: only targets that link CLI11 include it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "lightstage/memory.h"

namespace ls {

// Adds --memory SIZE to `command`, parsed into `budget` (refusals throw InputError naming the
// option: exit 2; a small budget's note is printed as a warning). `bounds` says what it bounds for
// this command (the table in lightstage/memory.h). The help ends with the units and the default:
// `unset` where the command has its own (import's), else `budget`'s (the benches set one).
inline CLI::Option* add_memory_option(CLI::App& command, MemoryBudget& budget,
                                      const std::string& bounds, std::string unset = {}) {
  if (unset.empty()) unset = budget.to_string();
  return command
      .add_option_function<std::string>(
          "--memory",
          [&budget](const std::string& text) {
            budget = MemoryBudget::parse(text);
            if (const std::string note = budget.note(); !note.empty()) {
              std::fprintf(stderr, "warning: %s\n", note.c_str());
            }
          },
          "The most memory this run holds for the field's data at once; larger work goes in "
          "bands of rows. " +
              bounds + " SIZE: bytes, or with K, M, G, T (powers of 1024: 512M, 2G, 1.5GiB). " +
              "Default: " + unset + ".")
      ->type_name("SIZE");
}

}  // namespace ls

#pragma once
// Previews laid out in a labelled grid (what a person looks at first after a relight).
#include <filesystem>
#include <string>
#include <vector>

namespace ls::jobs {

struct Preview {
  std::filesystem::path png;
  std::string label;
};

// Writes nothing for no tiles. Throws InputError naming a preview that cannot be read.
void write_contact_sheet(const std::filesystem::path& out, const std::vector<Preview>& tiles,
                         const std::string& title, int tile_size = 256, int max_columns = 4);

}  // namespace ls::jobs

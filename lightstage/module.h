#pragma once
// Modules: parts built as shared objects and loaded on first use, so that a library with a large
// load cost (OpenImageIO, OpenCV's video I/O: hundreds of libraries, 120 MiB resident) is in a
// process only when a job needs it. A module is found beside the program (../lib/lightstage/, for
// an installed tree) or in the build tree it was built in; LIGHTSTAGE_MODULE_DIR overrides both.
#include <string>

namespace ls {

// The address of `symbol` in module `name` (lib<name>.so), loading it the first time; it stays
// loaded. InputError naming the module, where it was looked for and why it failed.
void* module_symbol(const std::string& name, const char* symbol);

// True when module `name` has been loaded in this process.
bool module_loaded(const std::string& name);

}  // namespace ls

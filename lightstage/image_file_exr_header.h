#pragma once
// How OpenImageIO 2.4 presented an OpenEXR header, kept by lightstage's own EXR codec
// (image_file_exr.cc) so that the files written and read through OpenImageIO before read and
// write as they did: the channels' order, the attributes and their types, the compressions' names.
// Internal to the codec: its one user includes OpenEXR anyway.
#include <ImfForward.h>
#include <ImfPixelType.h>

#include <string>
#include <vector>

#include "lightstage/image_file.h"

namespace ls::image_file {

// A channel's name and its type in the file.
struct ExrChannel {
  std::string name;
  Imf::PixelType type;
};
// The header's channels as OpenImageIO ordered them (exrinput.cpp, query_channels): by layer (the
// name up to its last '.', the dot included), in byte order, the layerless first ("a-b." before
// "a."); within a layer R, G, B before A and the rest ("R", "Red", "G", "Green", "B", "Blue", "Y",
// "real", "imag", "A", "Alpha", "AR", "RA", "AG", "GA", "AB", "BA", "Z", "Depth", "Zback", in any
// case; in a layer with X and Y or Z, X, Y, Z follow Blue, as a position or normal reads); ties by
// name. OpenEXR itself keeps channels sorted by whole name.
std::vector<ExrChannel> exr_channels_in_oiio_order(const Imf::ChannelList& channels);

// The header's attributes but those Spec says otherwise (channels, windows, line order, tiles,
// ...): strings, ints, floats and doubles as themselves; "compression" as OpenImageIO named it
// ("none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"); others as
// OpenImageIO's text of them ("1, 2.5, 3"), typed by OpenEXR's name ("v3f").
std::vector<Attribute> exr_attributes(const Imf::Header& header);

// Spec's attributes into `header`: "compression" (a name above, "zip" when absent, "zip:N" or
// "dwaa:N" with a level); strings; long longs as ints; doubles typed "float" as floats, others as
// doubles. The reason when one cannot be; OpenEXR's exception when it refuses a name or value.
std::string set_exr_attributes(const Spec& spec, Imf::Header& header);

}  // namespace ls::image_file

// The live view's page (HTML, CSS and JavaScript in one document), embedded in the binary.
#pragma once

#include <string_view>

namespace mixray::liveview {

// The whole page served at "/". It opens a WebSocket to "/ws" on the same host, with the token
// of its own URL when that has one, and only receives: the tile list, images, overlays and
// figures (docs/live-view.md has the messages).
std::string_view pageHtml();

}  // namespace mixray::liveview

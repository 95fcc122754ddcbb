// Inside the reader cage: the ITK/GDCM adapter, the one place that drives
// ITK's ImageIO and GDCM. It implements volume_read.h's readers; the formats'
// own knowledge is in io/formats/.
#pragma once

namespace cinevol::itk_adapter {

// Registers the image formats cinevol reads and routes ITK/GDCM warnings away
// from stderr (failures still throw). Safe to call from any thread, often.
void InitToolkits();

// InitToolkits, and what the readers would otherwise set up at their first
// file (GDCM's dictionary, each format's reader): a child does it while it
// waits for its request, so that a load does not wait for it.
void WarmUp();

}  // namespace cinevol::itk_adapter

// shoal_channel_emulator: thin main; the app is channel_emulator/channel_emulator_app.
#include "channel_emulator/channel_emulator_app.h"

int main(int argc, char** argv) { return shoal::ChannelEmulatorMain(argc, argv); }

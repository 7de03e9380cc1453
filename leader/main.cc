// shoal_leader: the leader process (id 0). Thin main; the app is leader/leader_app.
#include "leader/leader_app.h"

int main(int argc, char** argv) { return shoal::LeaderMain(argc, argv); }

"""Navigation data: NMEA 0183 readers (`usvfast.nav.nmea`) and, later, AIS, pose tracks and
recording replay. Import from the submodules."""

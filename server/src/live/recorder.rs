//! The recorder actor: every detection, track estimate and API action of a session into SQLite.
//! (Being built: issue 12.)

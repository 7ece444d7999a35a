"""The diving agent's wire protocol: frames, messages and a streaming decoder (standard library only, no I/O)."""

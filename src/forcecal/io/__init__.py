"""Reading and writing the public file formats (INTERFACES.md sections 2-4)."""

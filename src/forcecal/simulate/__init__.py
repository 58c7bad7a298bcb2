"""The virtual rig (METHOD.md section 6): a finite-element beam, plate or block on stiff gauge
springs under an electromagnet with its coil circuit, its SLDV scan and its runs, measured
ideally or through a lab's imperfections, and written in the lab formats of INTERFACES.md."""
